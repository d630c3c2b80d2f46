//! [`CompensateJob`]: every option and input checked before any target is corrected, then
//! the run.

use std::path::{Path, PathBuf};

use adwi_robot::{Geometry, Joint, LinkNames, Robot};
use adwi_runtime::chain::JointKind;
use adwi_runtime::{AlignedBytes, Table};
use nalgebra::{Isometry3, Vector3};

use crate::bounds::frame_within;
use crate::correct::{self, Kinematics, Limits, Posture, TargetStatus, Turn};
use crate::frames::{angle_between, kuka_pose, orientation_values, rotation_of, FrameChain};
use crate::number::{rewrite, Number};
use crate::program::{ConfigHint, Format, FrameUse, Orientation, Program, Reason, TargetKind};
use crate::report::{CsvRows, Report, Summary, TargetLine};
use crate::source::Source;
use crate::Error;

/// What a compensation is asked to do. [`CompensateOptions::new`] gives the defaults.
#[derive(Clone, Debug)]
pub struct CompensateOptions {
    /// The correction table.
    pub table: PathBuf,
    /// The program.
    pub program: PathBuf,
    /// Where the compensated program goes, when the job writes it ([`CompensateJob::write`]):
    /// checked before any work never to be an input.
    pub output: Option<PathBuf>,
    /// Where the per-target report goes as CSV, likewise.
    pub report: Option<PathBuf>,
    /// The program's format; `None`: by the file's extension ([`Format::from_path`]).
    pub format: Option<Format>,
    /// A robot file (TOML, or URDF by `.urdf`), for joint targets, the inverse kinematics
    /// of a hybrid table's targets, and the posture checks.
    pub robot: Option<PathBuf>,
    /// The URDF chain's ends.
    pub links: LinkNames,
    /// The program's TCP in the flange frame, `[X, Y, Z, A, B, C]` (mm, KUKA degrees), for
    /// uses whose tool the program does not declare; `None`: the table's point.
    pub tool: Option<[f64; 6]>,
    /// The work object (base) in the robot's base frame, likewise; `None`: the base frame.
    pub base: Option<[f64; 6]>,
    /// A KUKA controller's `$config.dat` (or any file of `TOOL_DATA[n]={…}` and
    /// `BASE_DATA[n]={…}` lines): the numbered tools and bases a KRL program selects
    /// ([`crate::krl::read_config`]).
    pub krl_config: Option<PathBuf>,
    /// The table's measured point in the flange frame; `None`: a hybrid table's own (with
    /// a robot file), else the robot file's tool, else the flange.
    pub table_tool: Option<[f64; 6]>,
    /// The bounds of a correction.
    pub limits: Limits,
    /// Fail instead of leaving any target unchanged.
    pub strict: bool,
    /// The estimated seconds of work beyond which the job is refused before any.
    pub max_seconds: f64,
    /// The estimated memory beyond which the job is refused before any work, bytes
    /// ([`BYTES_PER_TARGET`] a target, and three times the program's size).
    pub max_memory_bytes: u64,
    /// A G-code program's A, B, C convention, work offsets and arc tolerance.
    pub gcode: crate::gcode::GcodeOptions,
    /// A Yaskawa job's numbered tools and user frames, and its axes' pulses per degree.
    pub yaskawa: crate::yaskawa::YaskawaOptions,
    /// A Fanuc program's numbered user and tool frames, and a frame file.
    pub fanuc: crate::fanuc::FanucOptions,
    /// The joints of a Fanuc CONFIG's three turn numbers, 1 for J1 (the controller's
    /// `$SCR_GRP[1].$TURN_AXIS`); `None`: the frame file's, else J4, J5, J6.
    pub fanuc_turn_axes: Option<[u8; 3]>,
    /// How a Fanuc pendant counts J3: the J3 it writes is the robot file's J3 plus this
    /// times J2 (1 where it counts J3 from the horizontal, the J2/J3 interaction of most
    /// Fanuc arms, and the robot file from the upper arm, as a ROS-Industrial URDF and
    /// every MD-H file do; 0 where both count alike). `None`: not said, and a Fanuc joint
    /// position is refused rather than read one way or the other.
    pub fanuc_j23: Option<f64>,
}

/// The default bound of a job's memory: 4 GiB, some two million targets.
pub const DEFAULT_MAX_MEMORY_BYTES: u64 = 4 << 30;

/// What a target is estimated to take from its reading to the written report, bytes: its
/// numbers, frames, report line, replacements and CSV row, with room for twelve joints
/// (about 1,300 bytes a target on average were measured for a million-row CSV of poses).
pub const BYTES_PER_TARGET: u64 = 2048;

/// The default bound of a correction: larger than any calibrated robot's error, small
/// enough to catch a table of another robot or a wrong frame.
pub const DEFAULT_MAX_CORRECTION_MM: f64 = 5.0;
/// The default bound of a joint's change, degrees: a correction of
/// [`DEFAULT_MAX_CORRECTION_MM`] turns an axis 150 mm from the TCP by 1.9°, so a normal
/// correction stays below it; a posture near a singularity, where a small Cartesian change
/// swings the wrist, goes beyond it.
pub const DEFAULT_MAX_JOINT_CHANGE_DEG: f64 = 2.0;

impl CompensateOptions {
    /// The defaults for `table` and `program`: 5 mm and 2° bounds, `tablec query`'s fixed
    /// point (1e-6 mm, 50 iterations), not strict, 300 s of work at most.
    pub fn new(table: impl Into<PathBuf>, program: impl Into<PathBuf>) -> CompensateOptions {
        CompensateOptions {
            table: table.into(),
            program: program.into(),
            output: None,
            report: None,
            format: None,
            robot: None,
            links: LinkNames::default(),
            tool: None,
            base: None,
            krl_config: None,
            table_tool: None,
            limits: Limits {
                max_correction_mm: DEFAULT_MAX_CORRECTION_MM,
                max_joint_change_deg: DEFAULT_MAX_JOINT_CHANGE_DEG,
                tolerance_mm: adwi_runtime::COMPENSATE_TOLERANCE_MM,
                max_iterations: adwi_runtime::COMPENSATE_ITERATIONS,
                beyond_evidence: false,
            },
            strict: false,
            max_seconds: 300.0,
            max_memory_bytes: DEFAULT_MAX_MEMORY_BYTES,
            gcode: crate::gcode::GcodeOptions::default(),
            yaskawa: crate::yaskawa::YaskawaOptions::default(),
            fanuc: crate::fanuc::FanucOptions::default(),
            fanuc_turn_axes: None,
            fanuc_j23: None,
        }
    }
}

impl CompensateOptions {
    /// Checks every option and every combination of options, reading no file: the
    /// program's format, by the option or the program's extension.
    ///
    /// # Errors
    ///
    /// [`Error::Option`], naming the first option refused.
    pub fn check(&self) -> Result<Format, Error> {
        let o = self;
        let limits = &o.limits;
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(limits.max_correction_mm)
            || !positive(limits.max_joint_change_deg)
            || !positive(limits.tolerance_mm)
            || limits.max_iterations == 0
        {
            return Err(Error::Option("max_correction_mm, max_joint_change_deg and the tolerance must be finite and positive, the iterations at least 1".into()));
        }
        let gcode = &o.gcode;
        if !positive(gcode.arc_tolerance_mm)
            || gcode
                .work_offsets
                .iter()
                .any(|(n, f)| !(54..=59).contains(n) || !crate::bounds::option_frame_within(f))
        {
            return Err(Error::Option(format!(
                "the arc tolerance must be finite and positive, and each work offset G54-G59 six numbers within ±{} mm and ±{}°",
                crate::bounds::MAX_POSITION_MM,
                crate::bounds::MAX_ANGLE_DEG
            )));
        }
        let yaskawa = &o.yaskawa;
        if let Some(per) = &yaskawa.pulses_per_deg {
            crate::yaskawa::check_pulses_per_deg(per).map_err(Error::Option)?;
        }
        if yaskawa
            .tools
            .iter()
            .chain(&yaskawa.users)
            .any(|(_, f)| !crate::bounds::option_frame_within(f))
        {
            return Err(Error::Option(format!(
                "each Yaskawa tool and user frame must be six numbers within ±{} mm and ±{}°",
                crate::bounds::MAX_POSITION_MM,
                crate::bounds::MAX_ANGLE_DEG
            )));
        }
        if o.fanuc
            .user_frames
            .iter()
            .chain(&o.fanuc.tool_frames)
            .any(|(n, f)| *n == 0 || !crate::bounds::option_frame_within(f))
        {
            return Err(Error::Option(format!(
                "each Fanuc user and tool frame must be numbered from 1 and six numbers within ±{} mm and ±{}°",
                crate::bounds::MAX_POSITION_MM,
                crate::bounds::MAX_ANGLE_DEG
            )));
        }
        if let Some(axes) = &o.fanuc_turn_axes {
            crate::fanuc::check_turn_axes(axes).map_err(Error::Option)?;
        }
        if o.fanuc_j23
            .is_some_and(|k| !(k.is_finite() && k.abs() <= 2.0))
        {
            return Err(Error::Option(
                "the Fanuc J2/J3 factor must be a number from -2 to 2 (1: the pendant counts J3 from the horizontal, 0: as the robot file)".into(),
            ));
        }
        if o.max_seconds.is_nan() || o.max_seconds <= 0.0 {
            return Err(Error::Option("max_seconds must be positive".into()));
        }
        for (name, frame) in [
            ("tool", &o.tool),
            ("base", &o.base),
            ("table tool", &o.table_tool),
        ] {
            if frame.is_some_and(|f| !crate::bounds::option_frame_within(&f)) {
                return Err(Error::Option(format!(
                    "the {name} must be six numbers X,Y,Z,A,B,C within ±{} mm and ±{}°",
                    crate::bounds::MAX_POSITION_MM,
                    crate::bounds::MAX_ANGLE_DEG
                )));
            }
        }
        let format = match o.format {
            Some(f) => f,
            None => Format::from_path(&o.program).ok_or_else(|| {
                Error::Option(format!(
                    "{}: cannot tell the program's format from its extension (.src, .dat, .mod, .modx, .prg, .sys, .sysx, .script, .urscript, .csv, .nc, .ngc, .gcode, .tap, .jbi, .ls, .pjx, .dtx); give it (krl, rapid, urscript, csv, gcode, yaskawa, fanuc, val3)",
                    o.program.display()
                ))
            })?,
        };
        if o.krl_config.is_some() && format != Format::Krl {
            return Err(Error::Option(
                "the KRL configuration (krl_config) is for KRL programs".into(),
            ));
        }
        if o.fanuc.frames_file.is_some() && format != Format::Fanuc {
            return Err(Error::Option(
                "the Fanuc frame file is for Fanuc programs".into(),
            ));
        }
        Ok(format)
    }
}

/// A compensated program: its bytes and the report.
#[derive(Clone, Debug)]
pub struct Compensated {
    /// The program with every corrected target's numbers replaced.
    pub output: Vec<u8>,
    /// Per target, what was done.
    pub report: Report,
}

/// A compensated program whose report was handed on line by line
/// ([`CompensateJob::run_each`]): its bytes, and the report's figures.
#[derive(Clone, Debug)]
pub struct Summarized {
    /// The program with every corrected target's numbers replaced.
    pub output: Vec<u8>,
    /// The report in figures.
    pub summary: Summary,
    /// The compensated program's xxh3-64 hash, as the report's rows name it.
    pub program_xxh3: u64,
}

/// A job whose options and inputs have all been checked: [`CompensateJob::run`] only
/// corrects.
pub struct CompensateJob {
    options: CompensateOptions,
    table: Table<AlignedBytes>,
    bytes: Vec<u8>,
    name: String,
    program: Program,
    kinematics: Option<Kinematics>,
    /// Per target, its frame chains (one per distinct use; none for joint targets), or why
    /// its frames are not known.
    /// A target's list is shared with the target before it when the two are the same (a
    /// long program's targets mostly are): one list, not one each.
    chains: Vec<Result<std::sync::Arc<[FrameChain]>, correct::Failure>>,
    /// The program and the report, checked before any work.
    outputs: adwi_output::OutputPlan,
    /// Whether the reader saw the program's motions (a KRL data list read without its
    /// `.src` did not), so that a declared target no motion moves to is unused.
    motions_seen: bool,
    /// A G-code program's arcs, per target (empty for other formats).
    arcs: Vec<Option<Box<crate::gcode::Arc>>>,
    /// The partner file's name as read (a KRL program's other file), where the report's
    /// lines `in_partner` are written.
    partner: Option<String>,
}

/// Estimated cost of one target, seconds: the fixed point alone, with a closed-form
/// inverse kinematics, with a numerical one — two to four times what was measured
/// (docs/programs.md, "Cost"), so that the estimate errs on the side of refusing.
const SECONDS_PER_TARGET: [f64; 3] = [1e-5, 3e-5, 2e-4];

/// How many bytes a program may have at most: read into memory whole.
const MAX_PROGRAM_BYTES: u64 = 1 << 30;

impl CompensateJob {
    /// Checks every option, opens the table and the robot, reads the program, resolves
    /// every target's frames and sizes the work — before any target is corrected.
    ///
    /// # Errors
    ///
    /// The first problem found: a bad option, an unreadable input, a malformed program
    /// (file, line and column), an output that is an input, or more work than
    /// `max_seconds`.
    pub fn new(options: CompensateOptions) -> Result<CompensateJob, Error> {
        let format = options.check()?;
        let o = &options;
        let mut inputs = Inputs::locate(o, format)?;
        let table = Table::from_vec(read_input(&o.table)?).map_err(|source| Error::Table {
            path: o.table.clone(),
            source,
        })?;
        let program_path = inputs.program_path(o);
        let bytes = read_program(program_path, inputs.partner.as_deref())?;
        let name = program_path.display().to_string();
        // Text a reader can read, in the dialect the job takes it for, before any work.
        crate::dialect::check(&Source::new(&name, &bytes), format, o.format.is_some())?;
        let frame_files = FrameFiles::read(o)?;
        let (kinematics, table_tool) = kinematics(o, &table, inputs.robot.take())?;
        if format == Format::Fanuc {
            let robot = kinematics.as_ref().map(Kinematics::robot);
            frame_files
                .fanuc_turn_axes
                .fit(robot)
                .map_err(Error::OptionMisfit)?;
        }
        let budget = Budget::new(o, kinematics.as_ref(), &name, bytes.len())?;
        let src = Source::new(&name, &bytes);
        let ReadProgram {
            mut program,
            arcs,
            work_offsets,
        } = read_targets(o, format, &src, &inputs, &frame_files, budget.limit)?;
        // A growing list reserves up to twice what it holds: the targets are kept to the run's
        // end.
        program.targets.shrink_to_fit();
        budget.refuse_truncated(&program)?;
        refuse_nothing_to_compensate(&src, &program, format, inputs.partner.as_deref())?;
        // A joint target's TCP matters where the table cannot turn its lever (a
        // correction of the point's whole pose carries every point the flange holds).
        let joint_levers = !table.has_orientation();
        let chains = FrameContext::new(o, &src, format, &program, &work_offsets, table_tool)
            .chains(&program, joint_levers)?;
        budget.refuse_too_long(program.targets.len())?;
        let motions_seen = match format {
            Format::Krl => inputs.partner.is_some() || program.first_motion.is_some(),
            Format::Rapid => true,
            Format::UrScript
            | Format::Csv
            | Format::Gcode
            | Format::Yaskawa
            | Format::Fanuc
            | Format::Val3 => false,
        };
        Ok(CompensateJob {
            motions_seen,
            partner: inputs.partner.as_ref().map(|p| p.display().to_string()),
            options,
            table,
            bytes,
            name,
            program,
            kinematics,
            chains,
            outputs: inputs.outputs,
            arcs,
        })
    }

    /// The program as read.
    pub fn program(&self) -> &Program {
        &self.program
    }

    /// The options, as checked.
    pub fn options(&self) -> &CompensateOptions {
        &self.options
    }

    /// The name of the program's partner file as read (a KRL `.dat`'s `.src` and back),
    /// where a report line `in_partner` is written; `None` when it has none.
    pub fn partner_name(&self) -> Option<&str> {
        self.partner.as_deref()
    }

    /// The characters of the widest place (`line:column`, as a report line gives it) of a
    /// target written in the program itself, 0 when it has none: a text report's place
    /// column is sized by it before the first line is printed.
    pub fn widest_place(&self) -> usize {
        let src = Source::new(&self.name, &self.bytes);
        let digits = |n: usize| n.checked_ilog10().map_or(1, |d| d as usize + 1);
        (0..self.program.targets.len())
            .map(|i| place(&src, &self.program, i))
            .filter(|&(_, _, in_partner)| !in_partner)
            .map(|(line, column, _)| digits(line) + 1 + digits(column))
            .max()
            .unwrap_or(0)
    }

    /// Corrects every target: the compensated program's bytes and the report.
    ///
    /// # Errors
    ///
    /// [`Error::NotAllCorrected`] when the job is strict and some target was not
    /// corrected.
    pub fn run(&self) -> Result<Compensated, Error> {
        let mut targets = Vec::with_capacity(self.program.targets.len());
        let done = self.run_each(|line| targets.push(line))?;
        Ok(Compensated {
            output: done.output,
            report: Report {
                targets,
                program_xxh3: Some(done.program_xxh3),
            },
        })
    }

    /// Corrects every target as [`CompensateJob::run`] does, but hands each target's report
    /// line to `each` as it is made, in the program's order, and keeps only the summary: a
    /// long program's lines need not be held to its end.
    ///
    /// # Errors
    ///
    /// As [`CompensateJob::run`] (`each` has then seen every line).
    pub fn run_each(&self, mut each: impl FnMut(TargetLine)) -> Result<Summarized, Error> {
        // The output written as the targets are corrected, when their replacements come in
        // the file's order (every reader's targets do, in practice); else, again, with
        // every replacement kept and sorted, the lines handed on already not handed again
        // (a run makes the same lines each time).
        let mut handed = 0;
        match self.run_with(true, &mut each, &mut handed)? {
            Some(done) => Ok(done),
            None => Ok(self
                .run_with(false, &mut each, &mut handed)?
                .expect("a run that keeps its replacements always finishes")),
        }
    }

    /// Corrects every target and writes the outputs (the program, and the report as CSV
    /// when the options name one), keeping of the report only its summary and the CSV's
    /// text; `each` sees every target's line as it is made.
    ///
    /// # Errors
    ///
    /// As [`CompensateJob::run`] and [`CompensateJob::write`]: nothing is then written.
    pub fn run_and_write(&self, mut each: impl FnMut(TargetLine)) -> Result<Summarized, Error> {
        let mut rows = (self.options.report.as_ref())
            .map(|_| CsvRows::with_capacity(self.program.targets.len()));
        let done = self.run_each(|line| {
            if let Some(rows) = &mut rows {
                rows.push(&line);
            }
            each(line);
        })?;
        let csv = rows.map(|rows| rows.finish(Some(done.program_xxh3)));
        self.write_bytes(&done.output, csv.as_deref())?;
        Ok(done)
    }

    /// [`CompensateJob::run_each`]: `streaming`, the output written as the targets come,
    /// `None` when a replacement comes before one written already; the lines from
    /// `handed` on handed to `each`, `handed` counting them.
    fn run_with(
        &self,
        streaming: bool,
        each: &mut impl FnMut(TargetLine),
        handed: &mut usize,
    ) -> Result<Option<Summarized>, Error> {
        let src = Source::new(&self.name, &self.bytes);
        let mut output = Output::new(streaming, &self.bytes, self.program.targets.len());
        let mut summary = Summary::default();
        // The first target not corrected, for a strict job's refusal.
        let mut first_not_corrected: Option<String> = None;
        let mut seed: Vec<f64> = self
            .kinematics
            .as_ref()
            .map_or_else(Vec::new, |k| k.robot().home().to_vec());
        let mut gcode = (self.program.format == Format::Gcode).then(|| GcodeEnds::new(&self.arcs));
        for (i, (target, chains)) in self.program.targets.iter().zip(&self.chains).enumerate() {
            let mut entry = report_line(&src, &self.program, i);
            let block = Block {
                src: &src,
                index: i,
                target,
                chains,
            };
            let result = self.target_edits(&block, &mut seed, &mut entry, gcode.as_ref());
            if let Some(gcode) = &mut gcode {
                gcode.record(i, target, &result);
            }
            match result {
                Ok(edits) => {
                    if !output.take(&self.bytes, edits) {
                        return Ok(None);
                    }
                }
                Err((status, detail)) => {
                    if let TargetStatus::BeyondEvidence(evidence) = status {
                        entry.evidence = Some(evidence);
                    }
                    entry.status = status;
                    entry.detail = detail;
                }
            }
            self.say_if_unused(target, &mut entry);
            say_notes(target, &mut entry);
            summary.add(&entry);
            if first_not_corrected.is_none() && !entry.status.corrected() {
                first_not_corrected = Some(not_corrected(&entry));
            }
            if i >= *handed {
                each(entry);
                *handed += 1;
            }
        }
        if let (true, Some(first)) = (self.options.strict, first_not_corrected) {
            return Err(Error::NotAllCorrected {
                not_corrected: summary.total - summary.corrected,
                total: summary.total,
                first,
            });
        }
        let output = output.finish(&self.bytes);
        let program_xxh3 = xxhash_rust::xxh3::xxh3_64(&output);
        Ok(Some(Summarized {
            output,
            summary,
            program_xxh3,
        }))
    }

    /// A target's edits (a G-code block's kept only where they may go, its arc's centre
    /// moved), never a non-finite number; or why it is left unchanged.
    fn target_edits(
        &self,
        block: &Block,
        seed: &mut Vec<f64>,
        entry: &mut TargetLine,
        gcode: Option<&GcodeEnds>,
    ) -> Result<Vec<Edit>, correct::Failure> {
        let edits = match (&block.target.refused, block.chains) {
            (Some(r), _) => Err((TargetStatus::Unaccounted(r.reason), r.detail.clone())),
            (None, Err(why)) => Err(why.clone()),
            (None, Ok(chains)) => {
                let mut end = None;
                let edits = self.target(block.src, block.target, chains, seed, entry, &mut end);
                match gcode {
                    Some(gcode) => {
                        let block = GcodeBlock {
                            src: block.src,
                            index: block.index,
                            chains,
                            end,
                            ends: &gcode.ends,
                            rewritten: &gcode.rewritten,
                        };
                        self.gcode_block(&block, edits, seed, entry)
                    }
                    None => edits,
                }
            }
        }?;
        // Never a non-finite number written, whatever the input held.
        let finite = edits.iter().all(|(_, text)| {
            crate::staubli::edit_number(text)
                .replace(',', ".")
                .parse::<f64>()
                .is_ok_and(f64::is_finite)
        });
        if finite {
            Ok(edits)
        } else {
            Err((
                TargetStatus::Invalid,
                "the command is not finite".to_string(),
            ))
        }
    }

    /// A declared target no motion moves to: corrected in the options' frames, and said
    /// to be unused.
    fn say_if_unused(&self, target: &crate::program::ProgramTarget, entry: &mut TargetLine) {
        let declared = self.motions_seen
            && matches!(
                target.kind,
                TargetKind::Cartesian(_) | TargetKind::Joints(_)
            );
        if declared && target.uses.is_empty() && target.refused.is_none() {
            let unused = "unused: no motion of the program moves to it";
            // Where nothing else was said, in which frames it was corrected.
            if matches!(target.kind, TargetKind::Cartesian(_)) && entry.detail.is_empty() {
                entry.add_detail(&format!("{unused}; in the options' frames"));
            } else {
                entry.add_detail(unused);
            }
        }
    }

    /// Writes the compensated program and the report where the options say, both or
    /// neither ([`adwi_output::OutputPlan`], checked when the job was made).
    ///
    /// # Errors
    ///
    /// [`Error::Write`] when a file cannot be written (none is then replaced).
    pub fn write(&self, done: &Compensated) -> Result<(), Error> {
        // The report's text only when it is written (some 250 bytes a target).
        let report = self.options.report.as_ref().map(|_| done.report.to_csv());
        self.write_bytes(&done.output, report.as_deref())
    }

    /// Writes the program's bytes and the report's CSV ([`CsvRows`]) where the options
    /// say, both or neither.
    ///
    /// # Errors
    ///
    /// As [`CompensateJob::write`].
    pub fn write_bytes(&self, output: &[u8], report: Option<&str>) -> Result<(), Error> {
        let mut contents: Vec<(&Path, &[u8])> = Vec::new();
        if let Some(path) = &self.options.output {
            contents.push((path, output));
        }
        if let (Some(path), Some(report)) = (&self.options.report, report) {
            contents.push((path, report.as_bytes()));
        }
        Ok(self.outputs.write(&contents)?)
    }

    /// One target's edits, its report filled in; or why it is left unchanged.
    fn target(
        &self,
        src: &Source,
        target: &crate::program::ProgramTarget,
        chains: &[FrameChain],
        seed: &mut Vec<f64>,
        entry: &mut TargetLine,
        end: &mut Option<[f64; 3]>,
    ) -> Result<Vec<Edit>, correct::Failure> {
        self.refuse_invalid(src, target, chains)?;
        match &target.kind {
            TargetKind::Incomplete(why) => Err((TargetStatus::Incomplete, why.clone())),
            // Always refused by its reader; no numbers to correct.
            TargetKind::Motion => Err((
                TargetStatus::Unaccounted(Reason::Dynamic),
                "no numbers written".into(),
            )),
            TargetKind::Cartesian(c) => self.cartesian(src, c, chains, seed, entry, end),
            TargetKind::Joints(j) => self.joints(src, j, chains, seed, entry),
        }
    }

    /// Refuses a target whose numbers, configuration or frames are out of bounds: an
    /// absurd value is reported where it is written, never iterated on.
    fn refuse_invalid(
        &self,
        src: &Source,
        target: &crate::program::ProgramTarget,
        chains: &[FrameChain],
    ) -> Result<(), correct::Failure> {
        // Every number within its bound before any arithmetic: an absurd value is reported
        // where it is written, never iterated on.
        let robot = self.kinematics.as_ref().map(Kinematics::robot);
        if let Some(why) = crate::bounds::out_of_range(src, &target.kind, robot) {
            return Err((TargetStatus::Invalid, why));
        }
        // A CSV's configuration is 0-254 as in sample files; a robot solved in closed form
        // has the eight of `adwi_robot::Configuration`.
        if let (TargetKind::Cartesian(c), Some(k)) = (&target.kind, &self.kinematics) {
            if let ConfigHint::Configuration(bits) = c.config {
                if bits >= 8 && k.has_configurations() {
                    return Err((
                        TargetStatus::Invalid,
                        format!("configuration {bits} is not one of the robot's 0-7"),
                    ));
                }
            }
            if let Some(why) = unmapped_configuration(src, &c.config, k) {
                return Err((TargetStatus::Invalid, why));
            }
        }
        if chains
            .iter()
            .any(|c| !(frame_within(&c.base) && frame_within(&c.tool)))
        {
            return Err((
                TargetStatus::Invalid,
                format!(
                    "its tool or work object is not within ±{} mm",
                    crate::bounds::MAX_POSITION_MM
                ),
            ));
        }
        Ok(())
    }

    /// A Cartesian target's edits: its pose through its frames to the table's point, the
    /// command solved there and written back in the program's frames and style.
    fn cartesian(
        &self,
        src: &Source,
        c: &crate::program::CartesianTarget,
        chains: &[FrameChain],
        seed: &mut Vec<f64>,
        entry: &mut TargetLine,
        end: &mut Option<[f64; 3]>,
    ) -> Result<Vec<Edit>, correct::Failure> {
        let limits = &self.options.limits;
        let [chain] = chains else {
            return Err((
                TargetStatus::AmbiguousFrame,
                format!("used with {} different tools or work objects", chains.len()),
            ));
        };
        let scale = c.unit.mm();
        let position = Vector3::from(c.position.map(|n| n.value * scale));
        let rotation = match &c.orientation {
            Some(o) => Some(rotation_of(o).ok_or_else(|| {
                (
                    TargetStatus::Incomplete,
                    "a zero quaternion is no orientation".to_string(),
                )
            })?),
            None => None,
        };
        let robot = self.kinematics.as_ref().map(Kinematics::robot);
        let given_joints: Option<Vec<f64>> = (!c.joints.is_empty())
            .then(|| joint_values_in(robot, &c.joints, adwi_samples::AngleUnit::Degree));
        // With the program's TCP the table's point, a position maps through the
        // work object alone (`W · p`): the orientation it does not write plays no
        // part, as in plain 3-axis G-code in G54.
        let position_maps = chain.tool == chain.table_tool;
        let (rotation, orientation) = match (rotation, &given_joints, &self.kinematics) {
            (Some(r), ..) => (r, true),
            // A CSV row's joints give the orientation the pose does not write.
            (None, Some(q), Some(k)) => match k.forward(q) {
                Some(p) => (p.rotation.to_rotation_matrix(), true),
                None => {
                    return Err((
                        TargetStatus::Incomplete,
                        format!(
                            "{} joint values for a robot of {}",
                            q.len(),
                            k.robot().joint_count()
                        ),
                    ))
                }
            },
            (None, ..) if position_maps && !self.table.is_hybrid() => {
                (nalgebra::Rotation3::identity(), false)
            }
            (None, ..) => return Err((
                TargetStatus::NeedsOrientation,
                "the target writes no orientation, which its frames or the table's posture need"
                    .into(),
            )),
        };
        let pose = Isometry3::from_parts(
            position.into(),
            nalgebra::UnitQuaternion::from_rotation_matrix(&rotation),
        );
        let point = chain.table_point(&pose);
        let near = given_joints.clone().unwrap_or_else(|| seed.clone());
        let posture = match &self.kinematics {
            Some(k) if orientation => written_posture(&c.config, k, &point, &near)?,
            k => posture(&c.config, k.as_ref()),
        };
        let command = correct::solve(
            &self.table,
            self.kinematics.as_ref(),
            limits,
            correct::Request {
                target: &point,
                orientation,
                posture: &posture,
                target_joints: given_joints.as_deref(),
                seed: &near,
                lever_mm: chain.lever_mm(),
            },
        );
        let command = command?;
        if let Some(q) = &command.target_joints {
            seed.clone_from(q);
        }
        let new_pose = chain.program_pose(&command.point);
        *end = Some(new_pose.translation.vector.into());
        let moved = (new_pose.translation.vector - pose.translation.vector).norm();
        let new_rotation = new_pose.rotation.to_rotation_matrix();
        let turned = angle_between(&new_rotation, &rotation);
        fill(
            entry,
            &point,
            &command,
            self.kinematics.as_ref(),
            moved,
            orientation.then_some(turned),
        );
        if moved > limits.max_correction_mm {
            return Err((
                TargetStatus::TooLarge,
                format!("{moved:.4} mm (bound {} mm)", limits.max_correction_mm),
            ));
        }
        Ok(self.cartesian_edits(src, c, &new_pose, turned, command.joints.as_deref()))
    }

    /// A corrected Cartesian target's numbers rewritten: its position, its orientation
    /// when the correction turns it, and the joints it writes beside them.
    fn cartesian_edits(
        &self,
        src: &Source,
        c: &crate::program::CartesianTarget,
        new_pose: &Isometry3<f64>,
        turned: f64,
        joints: Option<&[f64]>,
    ) -> Vec<Edit> {
        let bytes = src.bytes;
        let number_edit =
            |n: &Number, value: f64, decimals: usize| -> Option<((usize, usize), String)> {
                rewrite(n, &bytes[n.span.0..n.span.1], value, decimals).map(|text| (n.span, text))
            };
        let scale = c.unit.mm();
        let new_rotation = new_pose.rotation.to_rotation_matrix();
        // A Yaskawa controller holds positions in micrometres and 0.0001°, and its
        // jobs write them so: finer decimals are not its to read.
        let yaskawa = self.program.format == Format::Yaskawa;
        let (length_decimals, angle_decimals) = if yaskawa {
            (3, 4)
        } else {
            (c.unit.decimals(), 6)
        };
        let mut edits = Vec::new();
        // A VAL3 attribute the file omits (its number's span empty) is inserted.
        let names = crate::staubli::CARTESIAN;
        for (k, (n, v)) in c
            .position
            .iter()
            .zip(new_pose.translation.vector.iter())
            .enumerate()
        {
            edits.extend(
                number_edit(n, v / scale, length_decimals)
                    .map(|e| crate::staubli::inserted(e, names[k])),
            );
        }
        if let Some(o) = &c.orientation {
            // An orientation the correction does not turn keeps its numbers (and its
            // way of writing a rotation several ways, such as KUKA's at B = ±90°).
            if turned > 1e-12 {
                let values = orientation_values(o, &new_rotation);
                let (numbers, decimals): (&[Number], usize) = match o {
                    Orientation::KukaAbcDeg(n) => (n, angle_decimals),
                    Orientation::QuaternionWxyz(n) => (n, 9),
                    Orientation::RotationVectorRad(n) => (n, 8),
                    Orientation::XyzIntrinsicDeg(n) => (n, angle_decimals),
                };
                for (k, (n, v)) in numbers.iter().zip(values).enumerate() {
                    edits.extend(
                        number_edit(n, v, decimals)
                            .map(|e| crate::staubli::inserted(e, names[(k + 3).min(5)])),
                    );
                }
            }
        }
        if let Some(q) = joints {
            let robot = self.kinematics.as_ref().map(Kinematics::robot);
            for (i, (n, v)) in c.joints.iter().zip(q).enumerate() {
                let written = joint_value_out(robot, i, *v, adwi_samples::AngleUnit::Degree);
                edits.extend(number_edit(n, written, 6));
            }
        }
        edits
    }

    /// A joint target's edits: its joints through the forward kinematics, the command
    /// solved in the same configuration and written back as joints.
    fn joints(
        &self,
        src: &Source,
        j: &crate::program::JointTarget,
        chains: &[FrameChain],
        seed: &mut Vec<f64>,
        entry: &mut TargetLine,
    ) -> Result<Vec<Edit>, correct::Failure> {
        let limits = &self.options.limits;
        let bytes = src.bytes;
        let number_edit =
            |n: &Number, value: f64, decimals: usize| -> Option<((usize, usize), String)> {
                rewrite(n, &bytes[n.span.0..n.span.1], value, decimals).map(|text| (n.span, text))
            };
        let Some(k) = &self.kinematics else {
            return Err((
                TargetStatus::NeedsRobot,
                "joint targets need a robot file (or a hybrid table)".into(),
            ));
        };
        let n = k.robot().joint_count();
        if j.joints.len() != n {
            return Err((
                TargetStatus::Incomplete,
                format!("{} joint values for a robot of {n}", j.joints.len()),
            ));
        }
        // The TCP's lever from the table's point, where the table cannot turn it
        // (`FrameContext::chains`: no chain where it can).
        let lever_mm = match chains {
            [] => 0.0,
            [chain] => chain.lever_mm(),
            _ => {
                return Err((
                    TargetStatus::AmbiguousFrame,
                    format!("used with {} different tools", chains.len()),
                ))
            }
        };
        let mut q = joint_values_in(Some(k.robot()), &j.joints, j.unit);
        // Read as the pendant counts J3 (a factor other than zero only on three joints or
        // more).
        let j23 = self.fanuc_j23(k)?;
        if j23 != 0.0 {
            q[2] -= j23 * q[1];
        }
        let point = k.forward(&q).expect("one value per joint");
        let posture = Posture {
            configuration: k.configuration(&q),
            turns: Vec::new(),
        };
        seed.clone_from(&q);
        let command = correct::solve(
            &self.table,
            Some(k),
            limits,
            correct::Request {
                target: &point,
                orientation: true,
                posture: &posture,
                target_joints: Some(&q),
                seed: &q,
                lever_mm,
            },
        )?;
        let mut qc = command.joints.clone().unwrap_or_else(|| q.clone());
        // Written back as the pendant counts J3.
        if j23 != 0.0 {
            qc[2] += j23 * qc[1];
        }
        let moved = (command.point.translation.vector - point.translation.vector).norm();
        let turned = angle_between(
            &command.point.rotation.to_rotation_matrix(),
            &point.rotation.to_rotation_matrix(),
        );
        fill(entry, &point, &command, Some(k), moved, Some(turned));
        if moved > limits.max_correction_mm {
            return Err((
                TargetStatus::TooLarge,
                format!("{moved:.4} mm (bound {} mm)", limits.max_correction_mm),
            ));
        }
        // A Yaskawa job's joints are encoder pulses, written as whole pulses.
        let pulses = (self.program.format == Format::Yaskawa)
            .then_some(self.options.yaskawa.pulses_per_deg.as_ref())
            .flatten();
        Ok(j.joints
            .iter()
            .zip(&qc)
            .enumerate()
            .filter_map(|(i, (n, v))| match pulses.and_then(|p| p.get(i)) {
                Some(per_deg) => crate::yaskawa::pulse_text(
                    n,
                    &bytes[n.span.0..n.span.1],
                    joint_value_out(Some(k.robot()), i, *v, adwi_samples::AngleUnit::Degree),
                    *per_deg,
                )
                .map(|text| (n.span, text)),
                None => number_edit(
                    n,
                    joint_value_out(Some(k.robot()), i, *v, j.unit),
                    j.unit.decimals(),
                )
                .map(|e| crate::staubli::inserted(e, &crate::staubli::joint_name(i))),
            })
            .collect())
    }
}

impl CompensateJob {
    /// The factor a Fanuc joint position's J3 is written with (`J3 = J3_file + k·J2`),
    /// zero for the other dialects; a Fanuc joint position without it is refused, since
    /// either reading is confidently wrong for half the robot files (on an LR Mate read
    /// through a ROS-Industrial URDF as written, 0.095 mm mean where 0.004 mm was due).
    fn fanuc_j23(&self, k: &Kinematics) -> Result<f64, correct::Failure> {
        if self.program.format != Format::Fanuc || k.robot().joint_count() < 3 {
            return Ok(0.0);
        }
        let revolute = (1..3).all(|i| k.robot().joint_kind(i) == JointKind::Revolute);
        match self.options.fanuc_j23 {
            Some(k) if revolute || k == 0.0 => Ok(k),
            Some(_) => Err((
                TargetStatus::Invalid,
                "--fanuc-j23 couples J3 with J2, and one of them is prismatic".into(),
            )),
            None => Err((
                TargetStatus::Invalid,
                "a Fanuc pendant counts J3 from the horizontal on most arms (the J2/J3 interaction), a robot file from the upper arm: give --fanuc-j23 1 if it does so here (a ROS-Industrial URDF, any MD-H file), --fanuc-j23 0 if both count J3 alike".into(),
            )),
        }
    }
}

/// Joint `i`'s kind, when the robot has such a joint (a program may write more values
/// than the robot has joints: the count is checked where the values are used).
fn kind_of(robot: Option<&Robot>, i: usize) -> Option<JointKind> {
    robot
        .filter(|r| i < r.joint_count())
        .map(|r| r.joint_kind(i))
}

/// A program's joint values in the robot's units (rad; mm for a prismatic joint): an
/// angle in `unit`; a prismatic joint's length in mm where the program writes its angles
/// in degrees, in metres where it writes radians (SI, as URScript). Without a robot every
/// value is an angle.
fn joint_values_in(
    robot: Option<&Robot>,
    values: &[Number],
    unit: adwi_samples::AngleUnit,
) -> Vec<f64> {
    values
        .iter()
        .enumerate()
        .map(|(i, n)| match (kind_of(robot, i), unit) {
            (Some(JointKind::Prismatic), adwi_samples::AngleUnit::Degree) => n.value,
            (Some(JointKind::Prismatic), adwi_samples::AngleUnit::Radian) => n.value * 1000.0,
            _ => n.value * unit.rad(),
        })
        .collect()
}

/// Joint `i`'s value `v` in the robot's units as the program writes it: the inverse of
/// [`joint_values_in`].
fn joint_value_out(robot: Option<&Robot>, i: usize, v: f64, unit: adwi_samples::AngleUnit) -> f64 {
    match (kind_of(robot, i), unit) {
        (Some(JointKind::Prismatic), adwi_samples::AngleUnit::Degree) => v,
        (Some(JointKind::Prismatic), adwi_samples::AngleUnit::Radian) => v / 1000.0,
        _ => v / unit.rad(),
    }
}

/// A replacement: the bytes `start..end` of the program, and their new text.
type Edit = ((usize, usize), String);

/// A G-code target's block as the run has reached it.
struct GcodeBlock<'a> {
    src: &'a Source<'a>,
    /// The target's index.
    index: usize,
    chains: &'a [FrameChain],
    /// Its command's position, mm, its frame (when solved).
    end: Option<[f64; 3]>,
    /// The targets before it that an arc starts from: where each leaves the tool in the
    /// compensated program, by target, ascending.
    ends: &'a [(usize, [f64; 3])],
    /// The first bytes of the A, B, C numbers rewritten so far, ascending.
    rewritten: &'a [u32],
}

impl CompensateJob {
    /// A G-code target's edits kept only when they stay on its own block (the modal A, B,
    /// C another block writes are not rewritten, nor used when that block's were), and an
    /// arc's centre moved with its ends ([`crate::gcode::correct_arc`]).
    fn gcode_block(
        &self,
        block: &GcodeBlock,
        edits: Result<Vec<Edit>, correct::Failure>,
        seed: &[f64],
        entry: &TargetLine,
    ) -> Result<Vec<Edit>, correct::Failure> {
        let mut edits = edits?;
        let src = block.src;
        let target = &self.program.targets[block.index];
        let TargetKind::Cartesian(c) = &target.kind else {
            return Ok(edits);
        };
        let bytes = src.bytes;
        let line_start = bytes[..target.offset]
            .iter()
            .rposition(|b| *b == b'\n' || *b == b'\r')
            .map_or(0, |p| p + 1);
        let line_end = bytes[target.offset..]
            .iter()
            .position(|b| *b == b'\n' || *b == b'\r')
            .map_or(bytes.len(), |p| target.offset + p);
        let elsewhere = |n: &Number| n.span.0 < line_start || n.span.1 > line_end;
        if let Some(Orientation::KukaAbcDeg(abc)) = &c.orientation {
            if let Some(n) = abc.iter().find(|n| elsewhere(n)) {
                let (line, _) = src.location(n.span.0);
                let incomplete = |why: String| Err((TargetStatus::Incomplete, why));
                if edits
                    .iter()
                    .any(|((start, end), _)| *start < line_start || *end > line_end)
                {
                    return incomplete(format!(
                        "A, B, C not written on this block (modal from line {line}), and the correction turns the tool by {:.6}°",
                        entry.rotation_deg.unwrap_or(0.0)
                    ));
                }
                if abc.iter().any(|n| {
                    elsewhere(n)
                        && u32::try_from(n.span.0)
                            .is_ok_and(|s| block.rewritten.binary_search(&s).is_ok())
                }) {
                    return incomplete(format!(
                        "A, B, C not written on this block: modal from line {line}, whose A, B, C the correction rewrote"
                    ));
                }
            }
        }
        let Some(arc) = self.arcs.get(block.index).and_then(Option::as_ref) else {
            return Ok(edits);
        };
        let arc_refused = |why: String| Err((TargetStatus::Unaccounted(Reason::ArcTolerance), why));
        let start_out = block
            .ends
            .binary_search_by_key(&arc.start_target, |e| e.0)
            .ok()
            .map(|k| block.ends[k].1);
        let Some(start_out) = start_out else {
            return arc_refused("its start's block was not read as a target".into());
        };
        let end_mm = c.position.map(|n| n.value * c.unit.mm());
        let end_out = block.end.unwrap_or(end_mm);
        let [chain] = block.chains else {
            return arc_refused("its frames are not one".into());
        };
        let rotation = match &c.orientation {
            Some(o) => rotation_of(o),
            None => None,
        };
        let limits = &self.options.limits;
        let posture = Posture::default();
        let mut correct_point = |p: [f64; 3]| -> Result<[f64; 3], String> {
            let pose = Isometry3::from_parts(
                Vector3::from(p).into(),
                nalgebra::UnitQuaternion::from_rotation_matrix(
                    &rotation.unwrap_or_else(nalgebra::Rotation3::identity),
                ),
            );
            let point = chain.table_point(&pose);
            let command = correct::solve(
                &self.table,
                self.kinematics.as_ref(),
                limits,
                correct::Request {
                    target: &point,
                    orientation: rotation.is_some(),
                    posture: &posture,
                    target_joints: None,
                    seed,
                    lever_mm: chain.lever_mm(),
                },
            )
            .map_err(|(status, detail)| format!("{} {detail}", status.as_str()))?;
            Ok(chain.program_pose(&command.point).translation.vector.into())
        };
        let centre = crate::gcode::correct_arc(
            arc,
            end_mm,
            start_out,
            end_out,
            self.options.gcode.arc_tolerance_mm,
            &mut correct_point,
        );
        match centre {
            Ok(numbers) => {
                for (n, value) in numbers {
                    if let Some(text) =
                        rewrite(&n, &bytes[n.span.0..n.span.1], value, c.unit.decimals())
                    {
                        edits.push((n.span, text));
                    }
                }
                Ok(edits)
            }
            Err(why) => arc_refused(why),
        }
    }
}

/// The files a job reads beside its table and program, and its outputs, found and
/// checked before any is read.
struct Inputs {
    /// A KRL program's partner (read for the names its motions use).
    partner: Option<PathBuf>,
    /// A VAL3 application: its data file is the program whose numbers change, its project
    /// and programs are read beside it.
    application: Option<crate::staubli::Application>,
    /// The robot file's robot.
    robot: Option<Robot>,
    /// The program and the report, checked never to be an input.
    outputs: adwi_output::OutputPlan,
}

impl Inputs {
    /// Every file the job reads is an input no output may name, by any path: the table,
    /// the program, a KRL program's partner, a VAL3 application's files, the robot file
    /// and the URDF it names, the frame files.
    fn locate(o: &CompensateOptions, format: Format) -> Result<Inputs, Error> {
        let partner = match format {
            Format::Krl => partner(&o.program),
            _ => None,
        };
        let application = match format {
            Format::Val3 => Some(crate::staubli::Application::locate(&o.program)?),
            _ => None,
        };
        let (robot, robot_files) = match &o.robot {
            Some(path) => {
                let (robot, files) =
                    Robot::load_with_files(path, &o.links).map_err(|e| Error::Robot {
                        path: path.clone(),
                        message: e.to_string(),
                    })?;
                (Some(robot), files)
            }
            None => (None, Vec::new()),
        };
        let mut inputs: Vec<&Path> = vec![&o.table, &o.program];
        inputs.extend(partner.as_deref());
        inputs.extend(application.iter().flat_map(|a| a.files()));
        inputs.extend(o.robot.as_deref());
        inputs.extend(o.krl_config.as_deref());
        inputs.extend(o.fanuc.frames_file.as_deref());
        inputs.extend(robot_files.iter().map(PathBuf::as_path));
        let outputs = adwi_output::OutputPlan::check(
            &[o.output.as_deref(), o.report.as_deref()]
                .into_iter()
                .flatten()
                .collect::<Vec<_>>(),
            &inputs,
        )?;
        if let (Some(a), Some(b)) = (&o.output, &o.report) {
            if a == b {
                return Err(Error::Option(format!(
                    "the output and the report are both {}",
                    a.display()
                )));
            }
        }
        Ok(Inputs {
            partner,
            application,
            robot,
            outputs,
        })
    }

    /// The file whose numbers change: the program, or a VAL3 application's data file.
    fn program_path<'a>(&'a self, o: &'a CompensateOptions) -> &'a Path {
        self.application.as_ref().map_or(&o.program, |a| &a.data)
    }
}

/// A file's bytes, whole.
fn read_input(path: &Path) -> Result<Vec<u8>, Error> {
    adwi_runtime::input::read_regular(path).map_err(|source| Error::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// The program's bytes, it and its partner first bounded in size (both are read whole).
fn read_program(program_path: &Path, partner_path: Option<&Path>) -> Result<Vec<u8>, Error> {
    let size = std::fs::metadata(program_path)
        .map_err(|source| Error::Read {
            path: program_path.to_path_buf(),
            source,
        })?
        .len();
    if size > MAX_PROGRAM_BYTES {
        return Err(Error::Option(format!(
            "{}: {size} bytes, more than the {MAX_PROGRAM_BYTES} a program may have",
            program_path.display()
        )));
    }
    // The partner is read whole too: bounded as the program is, before it is read.
    if let Some(p) = partner_path {
        let partner_size = std::fs::metadata(p).map_or(0, |m| m.len());
        if partner_size > MAX_PROGRAM_BYTES {
            return Err(Error::Option(format!(
                "{}: {partner_size} bytes, more than the {MAX_PROGRAM_BYTES} a program's partner may have",
                p.display()
            )));
        }
    }
    read_input(program_path)
}

/// The frames a controller's files give: a KUKA `$config.dat`'s numbered tools and bases,
/// a Fanuc frame file's frames merged under the options'.
struct FrameFiles {
    krl: crate::krl::KrlFrames,
    fanuc: crate::fanuc::FanucOptions,
    fanuc_turn_axes: crate::fanuc::TurnAxes,
}

impl FrameFiles {
    /// Reads the files the options name (each checked, by [`CompensateOptions::check`],
    /// to be for the program's format).
    fn read(o: &CompensateOptions) -> Result<FrameFiles, Error> {
        let krl = match &o.krl_config {
            None => crate::krl::KrlFrames::default(),
            Some(path) => {
                let config = read_input(path)?;
                let config_name = path.display().to_string();
                crate::krl::read_config(&Source::new(&config_name, &config))?
            }
        };
        // A Fanuc frame file gives the frames the options do not.
        let mut controller_turn_axes = None;
        let fanuc = match &o.fanuc.frames_file {
            None => o.fanuc.clone(),
            Some(path) => {
                if std::fs::metadata(path).map_or(0, |m| m.len()) > MAX_PROGRAM_BYTES {
                    return Err(Error::Option(format!(
                        "{}: more than the {MAX_PROGRAM_BYTES} bytes a frame file may have",
                        path.display()
                    )));
                }
                let file = read_input(path)?;
                let file_name = path.display().to_string();
                let from_file = crate::fanuc::read_frames(&Source::new(&file_name, &file))?;
                controller_turn_axes =
                    crate::fanuc::read_turn_axes(&Source::new(&file_name, &file))?
                        .map(|axes| (axes, file_name));
                let mut merged = o.fanuc.clone();
                for (n, f) in from_file.user_frames {
                    if !merged.user_frames.iter().any(|u| u.0 == n) {
                        merged.user_frames.push((n, f));
                    }
                }
                for (n, f) in from_file.tool_frames {
                    if !merged.tool_frames.iter().any(|u| u.0 == n) {
                        merged.tool_frames.push((n, f));
                    }
                }
                merged
            }
        };
        let fanuc_turn_axes =
            crate::fanuc::TurnAxes::of_job(o.fanuc_turn_axes, controller_turn_axes)
                .map_err(Error::OptionMisfit)?;
        Ok(FrameFiles {
            krl,
            fanuc,
            fanuc_turn_axes,
        })
    }
}

/// The work and memory a program may take, known once the kinematics are: the program is
/// read only as far as they allow.
struct Budget {
    /// The program file, as named.
    name: String,
    /// Its size, bytes.
    bytes: usize,
    /// Estimated seconds a target.
    cost: f64,
    /// At most this many targets are read.
    limit: usize,
    /// The program, its output and its line starts, bytes.
    program_memory: u64,
    /// The targets the memory bound leaves room for.
    memory_targets: u64,
    /// The bounds.
    max_seconds: f64,
    max_memory_bytes: u64,
}

impl Budget {
    fn new(
        o: &CompensateOptions,
        kinematics: Option<&Kinematics>,
        name: &str,
        bytes: usize,
    ) -> Result<Budget, Error> {
        let cost = match kinematics {
            None => SECONDS_PER_TARGET[0],
            Some(k) if k.has_configurations() => SECONDS_PER_TARGET[1],
            Some(_) => SECONDS_PER_TARGET[2],
        };
        let limit = (o.max_seconds / cost).floor().min(usize::MAX as f64) as usize;
        // Memory: the program, its output and its line starts, and every target read; the
        // program is read only as far as the memory allows.
        let program_memory = 3 * bytes as u64;
        let memory_targets = o.max_memory_bytes.saturating_sub(program_memory) / BYTES_PER_TARGET;
        let budget = Budget {
            name: name.to_string(),
            bytes,
            cost,
            limit: limit.min(usize::try_from(memory_targets).unwrap_or(usize::MAX)),
            program_memory,
            memory_targets,
            max_seconds: o.max_seconds,
            max_memory_bytes: o.max_memory_bytes,
        };
        if program_memory > o.max_memory_bytes {
            return Err(budget.memory_refused(0, None));
        }
        Ok(budget)
    }

    fn memory_refused(&self, targets: usize, read_bytes: Option<usize>) -> Error {
        let scale = read_bytes.map_or(1.0, |at| self.bytes as f64 / at.max(1) as f64);
        Error::TooMuchMemory {
            file: self.name.clone(),
            bytes: self.bytes,
            targets,
            read_bytes,
            estimated_bytes: self.program_memory
                + (BYTES_PER_TARGET as f64 * targets as f64 * scale) as u64,
            limit_bytes: self.max_memory_bytes,
        }
    }

    /// Refuses a program whose reading stopped at the bound, by the bound it reached.
    fn refuse_truncated(&self, program: &Program) -> Result<(), Error> {
        let Some(at) = program.truncated_at else {
            return Ok(());
        };
        let targets = program.targets.len();
        if targets as u64 > self.memory_targets {
            return Err(self.memory_refused(targets, Some(at)));
        }
        Err(Error::TooLarge {
            file: self.name.clone(),
            bytes: self.bytes,
            targets,
            read_bytes: Some(at),
            seconds: self.cost * targets as f64 * self.bytes as f64 / at.max(1) as f64,
            limit_seconds: self.max_seconds,
        })
    }

    /// Refuses a program of more targets than the work allows.
    fn refuse_too_long(&self, targets: usize) -> Result<(), Error> {
        let seconds = self.cost * targets as f64;
        if seconds > self.max_seconds {
            return Err(Error::TooLarge {
                file: self.name.clone(),
                bytes: self.bytes,
                targets,
                read_bytes: None,
                seconds,
                limit_seconds: self.max_seconds,
            });
        }
        Ok(())
    }
}

/// A program as its dialect's reader read it, with what only G-code has.
struct ReadProgram {
    program: Program,
    /// A G-code program's arcs, per target.
    arcs: Vec<Option<Box<crate::gcode::Arc>>>,
    /// A G-code program's work offsets, per target.
    work_offsets: Vec<u8>,
}

/// The program's targets, by its dialect's reader, at most `limit` of them.
fn read_targets(
    o: &CompensateOptions,
    format: Format,
    src: &Source,
    inputs: &Inputs,
    frame_files: &FrameFiles,
    limit: usize,
) -> Result<ReadProgram, Error> {
    crate::bounds::check_line_lengths(src)?;
    let program = match format {
        Format::Krl => {
            let partner_path = &inputs.partner;
            let partner_bytes = partner_path
                .as_deref()
                .and_then(|p| adwi_runtime::input::read_regular(p).ok());
            let partner_name = partner_path
                .as_ref()
                .map(|p| p.display().to_string())
                .unwrap_or_default();
            let partner_src = partner_bytes
                .as_deref()
                .map(|b| Source::new(&partner_name, b));
            if let Some(p) = &partner_src {
                crate::bounds::check_line_lengths(p)?;
            }
            crate::krl::read_with(src, partner_src.as_ref(), &frame_files.krl, limit)?
        }
        Format::Rapid => crate::rapid::read_at_most(src, limit)?,
        Format::UrScript => crate::urscript::read_at_most(src, limit)?,
        Format::Csv => crate::csv::read_at_most(src, limit)?,
        Format::Gcode => {
            let read = crate::gcode::read_at_most(src, &o.gcode, limit)?;
            return Ok(ReadProgram {
                program: read.program,
                arcs: read.arcs,
                work_offsets: read.work_offsets,
            });
        }
        Format::Yaskawa => crate::yaskawa::read_at_most(src, &o.yaskawa, limit)?,
        Format::Fanuc => {
            crate::fanuc::read_at_most(src, &frame_files.fanuc, frame_files.fanuc_turn_axes, limit)?
        }
        Format::Val3 => {
            let files = inputs
                .application
                .as_ref()
                .map_or_else(|| Ok(Vec::new()), |a| a.read_programs())?;
            let programs: Vec<Source> = files.iter().map(|(n, b)| Source::new(n, b)).collect();
            crate::staubli::read_at_most(src, &programs, limit)?
        }
    };
    Ok(ReadProgram {
        program,
        arcs: Vec::new(),
        work_offsets: Vec::new(),
    })
}

/// A program that moves has targets: one whose targets this reader does not find
/// (another file's, another dialect's) is refused, never "0 of 0 corrected".
fn refuse_nothing_to_compensate(
    src: &Source,
    program: &Program,
    format: Format,
    partner_path: Option<&Path>,
) -> Result<(), Error> {
    let refused_all = program.targets.iter().all(|t| t.refused.is_some());
    let no_numbers = program
        .targets
        .iter()
        .all(|t| matches!(t.kind, TargetKind::Motion));
    let pair = format == Format::Krl && partner_path.is_some();
    if !(program.targets.is_empty()
        || (program.first_motion.is_some() && (no_numbers || (refused_all && pair))))
    {
        return Ok(());
    }
    let (at, message) = match program.first_motion {
        Some(at) => {
            let word = src.text(at, src.identifier_end(at, b"$#_"));
            let elsewhere = match (partner_path, format) {
                (Some(p), Format::Krl) if krl_partner_holds_targets(src, p) => format!(
                    ": its motions' targets are declared in {}; compensate that file (the motions that use them are read from this one)",
                    p.display()
                ),
                _ => program
                    .targets
                    .iter()
                    .find_map(|t| t.refused.as_ref())
                    .map_or(String::new(), |r| format!(" ({}: {})", r.reason.as_str(), r.detail)),
            };
            (at, format!("{word} moves the robot, but the program holds no target it can correct{elsewhere}"))
        }
        None => (
            0,
            format!(
                "no target and no motion found: nothing to compensate (is it a {} program?)",
                format.name()
            ),
        ),
    };
    Err(src.error(at, message))
}

/// Whether a KRL file's partner holds a target of its own to correct (read as the program,
/// `src` its partner): where it holds none, a refusal of `src` names `src`'s own reasons,
/// not the partner.
fn krl_partner_holds_targets(src: &Source, partner: &Path) -> bool {
    let Ok(bytes) = adwi_runtime::input::read_regular(partner) else {
        return false;
    };
    let name = partner.display().to_string();
    let partner = Source::new(&name, &bytes);
    // The first few answer it; a partner holding more is taken to hold targets.
    crate::krl::read_with(&partner, Some(src), &crate::krl::KrlFrames::default(), 256).is_ok_and(
        |p| {
            p.truncated_at.is_some()
                || p.targets
                    .iter()
                    .any(|t| !matches!(t.kind, TargetKind::Motion))
        },
    )
}

/// A target's frame chains, one per distinct use, or why its frames are not known.
type Chains = Result<std::sync::Arc<[FrameChain]>, correct::Failure>;

/// What resolves the frames of a program's uses: a use whose frame no input gives leaves
/// its target unchanged, said in its report line.
struct FrameContext<'a> {
    o: &'a CompensateOptions,
    src: &'a Source<'a>,
    format: Format,
    default_tool: Option<Isometry3<f64>>,
    default_base: Isometry3<f64>,
    /// The names the program's uses leave undeclared, tools first: the options stand for
    /// one undeclared tool and one undeclared work object.
    undeclared: [Vec<&'a str>; 2],
    /// A G-code program's work offsets, per target.
    work_offsets: &'a [u8],
    /// The table's point in the flange frame, when known.
    table_tool: Option<Isometry3<f64>>,
}

impl<'a> FrameContext<'a> {
    fn new(
        o: &'a CompensateOptions,
        src: &'a Source<'a>,
        format: Format,
        program: &'a Program,
        work_offsets: &'a [u8],
        table_tool: Option<Isometry3<f64>>,
    ) -> FrameContext<'a> {
        let pose = |t: [f64; 6]| kuka_pose([t[0], t[1], t[2]], [t[3], t[4], t[5]]);
        let mut undeclared: [Vec<&str>; 2] = [Vec::new(), Vec::new()];
        for target in program.targets.iter().filter(|t| t.refused.is_none()) {
            for m in target.uses.iter().flat_map(|u| &u.undeclared) {
                let names = &mut undeclared[usize::from(m.base)];
                if !names.contains(&m.name.as_str()) {
                    names.push(&m.name);
                }
            }
        }
        FrameContext {
            o,
            src,
            format,
            default_tool: o.tool.map(pose),
            default_base: o.base.map(pose).unwrap_or_else(Isometry3::identity),
            undeclared,
            work_offsets,
            table_tool,
        }
    }

    /// Every target's chains; a target's list shared with the target before it when the
    /// two are the same (a long program's targets mostly are): one list, not one each
    /// (168 bytes a chain).
    fn chains(&self, program: &Program, joint_levers: bool) -> Result<Vec<Chains>, Error> {
        let mut chains = Vec::with_capacity(program.targets.len());
        let mut last: Option<std::sync::Arc<[FrameChain]>> = None;
        for (index, target) in program.targets.iter().enumerate() {
            let list = match self.target_chains(index, target, joint_levers)? {
                Ok(list) => list,
                Err(why) => {
                    chains.push(Err(why));
                    continue;
                }
            };
            let shared = match &last {
                Some(l) if same_chains(l, &list) => l.clone(),
                _ => std::sync::Arc::from(list),
            };
            last = Some(shared.clone());
            chains.push(Ok(shared));
        }
        Ok(chains)
    }

    /// One target's distinct chains: none for a refused target, nor for a joint target
    /// unless `joint_levers` (then its tools alone, for their levers: joints place the
    /// flange whatever the work object).
    fn target_chains(
        &self,
        index: usize,
        target: &crate::program::ProgramTarget,
        joint_levers: bool,
    ) -> Result<Result<Vec<FrameChain>, correct::Failure>, Error> {
        let mut list: Vec<FrameChain> = Vec::new();
        let joints = match target.kind {
            TargetKind::Cartesian(_) => false,
            TargetKind::Joints(_) if joint_levers => true,
            _ => return Ok(Ok(list)),
        };
        if target.refused.is_some() {
            return Ok(Ok(list));
        }
        let default_use = [FrameUse {
            tool: None,
            base: self.work_offset(index),
            offset: target.offset,
            elsewhere: None,
            note: None,
            undeclared: Vec::new(),
            unknown: Vec::new(),
        }];
        let uses = if target.uses.is_empty() {
            &default_use[..]
        } else {
            &target.uses[..]
        };
        for u in uses {
            let (base, at) = (u.base, u.offset);
            let place = u.elsewhere.clone().unwrap_or_else(|| {
                let (line, column) = self.src.location(at);
                format!("{line}:{column}")
            });
            if let Some(why) = self.unknown(u, &place, joints) {
                return Ok(Err((TargetStatus::Unaccounted(Reason::FrameUnknown), why)));
            }
            let tool = u.tool.or(self.default_tool);
            let base = if joints {
                Some(Isometry3::identity())
            } else {
                base
            };
            let chain = match (tool, self.table_tool) {
                (None, _) => FrameChain {
                    base: base.unwrap_or(self.default_base),
                    tool: Isometry3::identity(),
                    table_tool: Isometry3::identity(),
                },
                (Some(tool), Some(table_tool)) => FrameChain {
                    base: base.unwrap_or(self.default_base),
                    tool,
                    table_tool,
                },
                (Some(_), None) if joints => {
                    return Ok(Err((
                        TargetStatus::Unaccounted(Reason::FrameUnknown),
                        format!("its tool (used at {place}) is not placed against the table's point, whose place on the flange is not known: give the table tool or a robot file"),
                    )));
                }
                (Some(_), None) => {
                    return Err(self.src.error(at, "this use names a tool, but where the table's point is on the flange is not known: give the table tool or a robot file"));
                }
            };
            if !list.iter().any(|c| same_chain(c, &chain)) {
                list.push(chain);
            }
        }
        Ok(Ok(list))
    }

    /// A G-code target's work offset, by its number.
    fn work_offset(&self, index: usize) -> Option<Isometry3<f64>> {
        let number = self.work_offsets.get(index)?;
        let f = self.o.gcode.work_offsets.iter().find(|w| w.0 == *number)?.1;
        Some(kuka_pose([f[0], f[1], f[2]], [f[3], f[4], f[5]]))
    }

    /// Why a use's frames are not known: a frame its reader could not resolve, or one it
    /// leaves undeclared that the options do not give (or give for another name too);
    /// with `tools_only`, an undeclared work object is no reason (a joint target's).
    fn unknown(&self, u: &FrameUse, place: &str, tools_only: bool) -> Option<String> {
        if let Some(why) = u.unknown.first() {
            return Some(format!("{why} (used at {place})"));
        }
        let o = self.o;
        for m in u.undeclared.iter().filter(|m| !(tools_only && m.base)) {
            let (given, option) = if m.base {
                (o.base.is_some(), "base")
            } else {
                (o.tool.is_some(), "tool")
            };
            let numbered = self.format == Format::Krl
                && (m.name.starts_with("TOOL_DATA") || m.name.starts_with("BASE_DATA"));
            let yaskawa_number = (self.format == Format::Yaskawa)
                .then(|| m.name.split_once(' ').map(|(_, n)| n))
                .flatten();
            let how = if let Some(n) = yaskawa_number {
                let flag = if m.base { "user" } else { "tool" };
                format!("give it as --yaskawa-{flag} {n}=X,Y,Z,Rx,Ry,Rz, or as the {option} option")
            } else if numbered {
                format!(
                    "give it in the KRL configuration (--krl-config), or as the {option} option"
                )
            } else {
                format!("give it as the {option} option")
            };
            let names = &self.undeclared[usize::from(m.base)];
            if !given {
                return Some(format!(
                    "{} not given (used at {place}): {how}",
                    m.describe()
                ));
            }
            if names.len() > 1 {
                return Some(format!(
                    "{} not given (used at {place}): the {option} option stands for one, and the program names {}",
                    m.describe(),
                    names.join(", ")
                ));
            }
        }
        None
    }
}

/// Whether two lists of frame chains are the same to rounding.
fn same_chains(a: &[FrameChain], b: &[FrameChain]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(a, b)| same_chain(a, b))
}

/// A target as the run reaches it.
struct Block<'a> {
    src: &'a Source<'a>,
    /// The target's index.
    index: usize,
    target: &'a crate::program::ProgramTarget,
    chains: &'a Chains,
}

/// Where target `index` is written: its line and column, in the partner file (`true`) or
/// in the program.
fn place(src: &Source, program: &Program, index: usize) -> (usize, usize, bool) {
    match program.partner_place(index) {
        Some(p) => (p.line, p.column, true),
        None => {
            let (line, column) = src.location(program.targets[index].offset);
            (line, column, false)
        }
    }
}

/// Target `index`'s report line before it is corrected: where it is written and what it
/// is.
fn report_line(src: &Source, program: &Program, index: usize) -> TargetLine {
    let target = &program.targets[index];
    let (line, column, in_partner) = place(src, program, index);
    TargetLine {
        name: target.name.clone(),
        line,
        column,
        in_partner,
        kind: match target.kind {
            TargetKind::Cartesian(_) => "cartesian",
            TargetKind::Joints(_) => "joints",
            TargetKind::Incomplete(_) => "incomplete",
            TargetKind::Motion => "motion",
        },
        status: TargetStatus::Ok,
        detail: String::new(),
        correction_mm: None,
        rotation_deg: None,
        joint_change_deg: None,
        point_mm: None,
        command_mm: None,
        command_joints: None,
        iterations: 0,
        residual_mm: None,
        residual: None,
        evidence: None,
    }
}

/// A target left unchanged, as a strict job's refusal names it.
fn not_corrected(entry: &TargetLine) -> String {
    format!(
        "{} {}{}",
        entry.place(),
        entry.status.as_str(),
        if entry.detail.is_empty() {
            String::new()
        } else {
            format!(": {}", entry.detail)
        }
    )
}

/// The compensated program as the run makes it.
enum Output {
    /// Written as the targets come: the output so far, and the byte of the program it has
    /// reached.
    Streaming { bytes: Vec<u8>, at: usize },
    /// Every target's replacements kept, their texts one after the other in `texts` (a
    /// few dozen bytes a number rather than a string each), written at the end.
    Kept {
        edits: Vec<((usize, usize), std::ops::Range<usize>)>,
        texts: String,
    },
}

impl Output {
    fn new(streaming: bool, program: &[u8], targets: usize) -> Output {
        if !streaming {
            return Output::Kept {
                edits: Vec::new(),
                texts: String::new(),
            };
        }
        // A rewritten target grows by some 27 bytes (a G-code block's A, B, C from `0.` to
        // `6.030297`): reserved once, not grown by doubling.
        let mut bytes = Vec::new();
        bytes.reserve_exact(program.len().saturating_add(targets.saturating_mul(32)));
        Output::Streaming { bytes, at: 0 }
    }

    /// Takes a target's edits; `false` when one comes before the bytes written already.
    fn take(&mut self, program: &[u8], mut new_edits: Vec<Edit>) -> bool {
        match self {
            Output::Streaming { bytes, at } => {
                new_edits.sort_by_key(|(span, _)| span.0);
                for ((start, end), text) in new_edits {
                    if start < *at {
                        return false;
                    }
                    // Grown an eighth at a time: a rewritten number is longer than the
                    // written one, by an unknown share of the program.
                    let more = start - *at + text.len();
                    if bytes.capacity() - bytes.len() < more {
                        bytes.reserve_exact(more.max(bytes.capacity() / 8));
                    }
                    bytes.extend_from_slice(&program[*at..start]);
                    bytes.extend_from_slice(text.as_bytes());
                    *at = end;
                }
            }
            Output::Kept { edits, texts } => {
                for (span, text) in new_edits {
                    let start = texts.len();
                    texts.push_str(&text);
                    edits.push((span, start..texts.len()));
                }
            }
        }
        true
    }

    /// The compensated program's bytes.
    fn finish(self, program: &[u8]) -> Vec<u8> {
        let (mut output, at) = match self {
            Output::Streaming { bytes, at } => (bytes, at),
            Output::Kept { mut edits, texts } => {
                edits.sort_by_key(|(span, _)| span.0);
                let mut output = Vec::new();
                output.reserve_exact(program.len() + texts.len());
                let mut at = 0;
                for ((start, end), text) in edits {
                    debug_assert!(start >= at, "targets never overlap");
                    output.extend_from_slice(&program[at..start]);
                    output.extend_from_slice(&texts.as_bytes()[text]);
                    at = end;
                }
                (output, at)
            }
        };
        output.extend_from_slice(&program[at..]);
        output
    }
}

/// A G-code program's run so far: where each target's block an arc starts from leaves
/// the tool in the compensated program (mm, its frame), and the A, B, C numbers rewritten
/// (their first byte). Only the ends an arc starts from are kept, by target, and the
/// bytes as u32 (a program has at most 2^30): a long program's few bytes a target.
struct GcodeEnds {
    /// The targets an arc starts from, ascending.
    arc_starts: Vec<usize>,
    ends: Vec<(usize, [f64; 3])>,
    rewritten: Vec<u32>,
}

impl GcodeEnds {
    fn new(arcs: &[Option<Box<crate::gcode::Arc>>]) -> GcodeEnds {
        let mut arc_starts: Vec<usize> = arcs.iter().flatten().map(|a| a.start_target).collect();
        arc_starts.sort_unstable();
        arc_starts.dedup();
        GcodeEnds {
            arc_starts,
            ends: Vec::new(),
            rewritten: Vec::new(),
        }
    }

    /// Records where target `i`'s block leaves the tool, and the A, B, C it rewrote.
    fn record(
        &mut self,
        i: usize,
        target: &crate::program::ProgramTarget,
        result: &Result<Vec<Edit>, correct::Failure>,
    ) {
        let end = match (&target.kind, result) {
            (TargetKind::Cartesian(c), Ok(edits)) => {
                let mut end = c.position.map(|n| n.value);
                let from = self.rewritten.len();
                for ((start, _), text) in edits {
                    if let Some(k) = c.position.iter().position(|n| n.span.0 == *start) {
                        end[k] = text.parse().unwrap_or(end[k]);
                    } else if let Some(Orientation::KukaAbcDeg(abc)) = &c.orientation {
                        if abc.iter().any(|n| n.span.0 == *start) {
                            self.rewritten.extend(u32::try_from(*start).ok());
                        }
                    }
                }
                // Ascending: the targets are in the file's order, and a block's own
                // numbers (C, B, A in the fixed-axis convention) sorted.
                self.rewritten[from..].sort_unstable();
                Some(end.map(|v| v * c.unit.mm()))
            }
            (TargetKind::Cartesian(c), Err(_)) => Some(c.position.map(|n| n.value * c.unit.mm())),
            _ => None,
        };
        if let (Some(end), Ok(_)) = (end, self.arc_starts.binary_search(&i)) {
            self.ends.push((i, end));
        }
    }
}

/// The report's figures of a solved command.
fn fill(
    entry: &mut TargetLine,
    point: &Isometry3<f64>,
    command: &correct::Command,
    kinematics: Option<&Kinematics>,
    moved: f64,
    turned: Option<f64>,
) {
    entry.correction_mm = Some(moved);
    entry.point_mm = Some(point.translation.vector.into());
    entry.command_mm = Some(command.point.translation.vector.into());
    entry.rotation_deg = turned.map(f64::to_degrees);
    // A turn the robot cannot give its tool (fewer than six joints): said, never hidden in
    // an `ok`. A microradian is below any tool's use.
    if let (Some(k), true) = (kinematics, command.unturned_rad > 1e-6) {
        entry.detail = format!(
            "orientation: {:.3} mrad of the correction's turn is beyond the {} joints' reach, \
             left uncorrected; the position is corrected",
            command.unturned_rad * 1e3,
            k.robot().joint_count()
        );
    }
    entry.iterations = command.iterations;
    entry.residual_mm = Some(command.residual_mm);
    entry.residual = Some(command.residual);
    entry.evidence = Some(command.evidence);
    if let (Some(k), Some(a), Some(b)) = (kinematics, &command.target_joints, &command.joints) {
        entry.joint_change_deg = Some(correct::joint_change(k.robot(), a, b));
    }
    if let (Some(k), Some(q)) = (kinematics, &command.joints) {
        entry.command_joints = Some(
            q.iter()
                .enumerate()
                .map(|(i, v)| match k.robot().joint_kind(i) {
                    adwi_runtime::chain::JointKind::Revolute => v.to_degrees(),
                    adwi_runtime::chain::JointKind::Prismatic => *v,
                })
                .collect(),
        );
    }
}

/// Whether two frame chains are the same to rounding.
fn same_chain(a: &FrameChain, b: &FrameChain) -> bool {
    let close = |x: &Isometry3<f64>, y: &Isometry3<f64>| {
        (x.to_homogeneous() - y.to_homogeneous()).abs().max() < 1e-9
    };
    close(&a.base, &b.base) && close(&a.tool, &b.tool) && close(&a.table_tool, &b.table_tool)
}

/// The other file of a KRL `.src`/`.dat` pair, when it exists.
fn partner(program: &Path) -> Option<PathBuf> {
    let ext = program.extension()?.to_str()?;
    let other = match ext.to_ascii_lowercase().as_str() {
        "src" => "dat",
        "dat" => "src",
        _ => return None,
    };
    [other.to_string(), other.to_ascii_uppercase()]
        .into_iter()
        .map(|e| program.with_extension(e))
        .find(|p| p.is_file())
}

/// The posture a program writes, in this project's configuration labels.
fn posture(hint: &ConfigHint, kinematics: Option<&Kinematics>) -> Posture {
    let joints = kinematics.map_or(6, |k| k.robot().joint_count());
    let configuration = |bits: u8| adwi_robot::Configuration::from_bits(bits);
    match *hint {
        ConfigHint::None => Posture::default(),
        ConfigHint::Configuration(bits) => Posture {
            configuration: configuration(bits),
            turns: Vec::new(),
        },
        ConfigHint::KukaStatusTurn { status, turn } => Posture {
            // KUKA S: bit 0 overhead (shoulder back), bit 1 A3 ≥ φ (elbow up), bit 2 A5 ≤ 0.
            configuration: status
                .and_then(|s| configuration(((s & 1) | (((s >> 1) & 1) ^ 1) << 1 | (s & 4)) as u8)),
            turns: turn.map_or_else(Vec::new, |t| {
                (0..joints.min(6))
                    .map(|i| Turn::Negative((t >> i) & 1 == 1))
                    .collect()
            }),
        },
        ConfigHint::RapidConf([cf1, cf4, cf6, cfx]) => Posture {
            // ABB cfx: bit 0 axis 5 negative, bit 1 backward (elbow down), bit 2 behind.
            configuration: (0..8)
                .contains(&cfx)
                .then(|| configuration((((cfx >> 2) & 1) | (cfx & 2) | ((cfx & 1) << 2)) as u8))
                .flatten(),
            turns: (0..joints.min(6))
                .map(|i| match i {
                    0 => Turn::Quadrant(cf1),
                    3 => Turn::Quadrant(cf4),
                    5 => Turn::Quadrant(cf6),
                    _ => Turn::Any,
                })
                .collect(),
        },
        // Resolved on the robot's geometry by `written_posture`; nothing to keep without
        // a robot, or when unreadable (refused before).
        ConfigHint::Val3 { .. }
        | ConfigHint::YaskawaRconf { .. }
        | ConfigHint::Unreadable { .. } => Posture::default(),
        ConfigHint::FanucConfig {
            configuration: bits,
            turns,
            turn_axes,
        } => Posture {
            configuration: bits.and_then(configuration),
            turns: crate::fanuc::joint_turns(&turns, &turn_axes, joints),
        },
    }
}

/// Why a configuration the target writes cannot be kept on the robot: unreadable as
/// written, or written for an arm with shoulder, elbow and wrist labels the robot has not
/// (no closed-form inverse kinematics: seven axes, a wrist that is not spherical). `None`
/// when it can, or when nothing is written.
fn unmapped_configuration(src: &Source, hint: &ConfigHint, k: &Kinematics) -> Option<String> {
    let unmapped = "left as written, not corrected in a posture the program does not give";
    match *hint {
        ConfigHint::Unreadable { span, expected } => {
            let (line, column) = src.location(span.0);
            let found = if span.1 > span.0 {
                format!("'{}'", src.text(span.0, span.1))
            } else {
                src.describe(span.0)
            };
            Some(format!(
                "{expected}, found {found} (line {line}, column {column}): {unmapped}"
            ))
        }
        ConfigHint::Val3 { .. }
        | ConfigHint::YaskawaRconf { .. }
        | ConfigHint::KukaStatusTurn {
            status: Some(_), ..
        }
        | ConfigHint::RapidConf(_)
        | ConfigHint::FanucConfig {
            configuration: Some(_),
            ..
        } if !k.has_configurations() => Some(format!(
            "the written configuration ({}) cannot be told apart on this robot file ({}): {unmapped}",
            written_configuration(hint),
            k.without_configurations().unwrap_or_default()
        )),
        _ => crate::fanuc::unheld_turn(hint, k.robot()),
    }
}

/// A VAL3 `config` or a Yaskawa `///RCONF` in words, for the report.
fn written_configuration(hint: &ConfigHint) -> String {
    let either = |v: Option<bool>, yes: &str, no: &str, free: &str| match v {
        Some(true) => yes.to_string(),
        Some(false) => no.to_string(),
        None => free.to_string(),
    };
    match *hint {
        ConfigHint::Val3 {
            righty,
            elbow_positive,
            wrist_positive,
        } => format!(
            "shoulder {}, elbow {}, wrist {}",
            either(righty, "righty", "lefty", "free"),
            either(elbow_positive, "epositive", "enegative", "free"),
            either(wrist_positive, "wpositive", "wnegative", "free")
        ),
        ConfigHint::YaskawaRconf {
            no_flip,
            lower_arm,
            rear,
            at_least_180: [r, t, s],
        } => {
            let angle = |axis: &str, at_least: bool| {
                format!("{axis} {} 180°", if at_least { "≥" } else { "<" })
            };
            format!(
                "RCONF {}, {}, {}, {}, {}, {}",
                if no_flip { "no flip" } else { "flip" },
                if lower_arm { "lower arm" } else { "upper arm" },
                if rear { "rear" } else { "front" },
                angle("R", r),
                angle("T", t),
                angle("S", s)
            )
        }
        ConfigHint::FanucConfig {
            configuration: Some(bits),
            turns,
            ..
        } => {
            let turn = |t: Option<i8>| t.map_or_else(|| "?".to_string(), |t| t.to_string());
            format!(
                "CONFIG '{} {} {}, {}, {}, {}'",
                if bits & 4 != 0 { "F" } else { "N" },
                if bits & 2 != 0 { "D" } else { "U" },
                if bits & 1 != 0 { "B" } else { "T" },
                turn(turns[0]),
                turn(turns[1]),
                turn(turns[2])
            )
        }
        ConfigHint::KukaStatusTurn { status, turn } => {
            let bits = |v: Option<u32>| v.map_or_else(|| "?".to_string(), |v| format!("'B{v:b}'"));
            format!("S {}, T {}", bits(status), bits(turn))
        }
        ConfigHint::RapidConf([cf1, cf4, cf6, cfx]) => format!("robconf [{cf1},{cf4},{cf6},{cfx}]"),
        _ => String::new(),
    }
}

/// The posture the target's configuration writes, resolved at the target `point` on the
/// robot's geometry where the vendor defines it by joint values: a VAL3 `config` (the
/// shoulder a label, the elbow and wrist the signs of J3 and J5) and a Yaskawa `///RCONF`
/// (the shoulder and arm labels, the flip J4 within (−90°, 90°] turn for turn, the R, T
/// and S axes at 180° or more). The label taken is the one nearest `near` among those the
/// written parts allow (the controller's choice where a part is free); the command keeps
/// it and the joint constraints. Other hints as [`posture`] maps them.
fn written_posture(
    hint: &ConfigHint,
    k: &Kinematics,
    point: &Isometry3<f64>,
    near: &[f64],
) -> Result<Posture, correct::Failure> {
    let any = vec![Turn::Any; k.robot().joint_count()];
    let fail = || {
        (
            TargetStatus::IkFailed,
            format!(
                "no posture reaches the target in its written configuration ({})",
                written_configuration(hint)
            ),
        )
    };
    match *hint {
        ConfigHint::Val3 {
            righty,
            elbow_positive,
            wrist_positive,
        } => {
            let mut turns = any;
            if let Some(positive) = elbow_positive {
                turns[2] = Turn::Negative(!positive);
            }
            if let Some(positive) = wrist_positive {
                turns[4] = Turn::Negative(!positive);
            }
            let labels = (0u8..8).filter(|b| righty.is_none_or(|r| (b & 1 == 1) == r));
            let (configuration, _) =
                nearest_label(k, point, near, labels, &turns, |_| true).ok_or_else(fail)?;
            Ok(Posture {
                configuration: Some(configuration),
                turns,
            })
        }
        ConfigHint::YaskawaRconf {
            no_flip,
            lower_arm,
            rear,
            at_least_180,
        } => {
            let labels = u8::from(rear) | u8::from(lower_arm) << 1;
            // Flip: J4 within (−90°, 90°] turn for turn; one of the two wrists has it.
            let flip = |q: &[f64]| {
                let r = q[3].to_degrees().rem_euclid(360.0);
                let flipped = r <= 90.0 || r > 270.0;
                flipped != no_flip
            };
            let (configuration, q) =
                nearest_label(k, point, near, [labels, labels | 4].into_iter(), &any, flip)
                    .ok_or_else(fail)?;
            // R (J4), T (J6), S (J1) under 180° or not: the turn nearest `near` that holds.
            let mut turns = any;
            for (joint, at_least) in [
                (3, at_least_180[0]),
                (5, at_least_180[1]),
                (0, at_least_180[2]),
            ] {
                let [lower, upper] = k.robot().joints()[joint].limits;
                let seed = near.get(joint).copied().unwrap_or(q[joint]);
                let v = (-2..=2)
                    .map(|t| q[joint] + std::f64::consts::TAU * f64::from(t))
                    .filter(|v| (lower..=upper).contains(v))
                    .filter(|v| (v.to_degrees() >= 180.0) == at_least)
                    .min_by(|a, b| (a - seed).abs().total_cmp(&(b - seed).abs()))
                    .ok_or_else(fail)?;
                turns[joint] = Turn::Revolution(((v.to_degrees() - 180.0) / 360.0).ceil() as i64);
            }
            Ok(Posture {
                configuration: Some(configuration),
                turns,
            })
        }
        _ => Ok(posture(hint, Some(k))),
    }
}

/// The configuration label among `labels` whose posture reaching `point` with `turns`
/// and holding `holds` lies nearest `near`, with that posture.
fn nearest_label(
    k: &Kinematics,
    point: &Isometry3<f64>,
    near: &[f64],
    labels: impl Iterator<Item = u8>,
    turns: &[Turn],
    holds: impl Fn(&[f64]) -> bool,
) -> Option<(adwi_robot::Configuration, Vec<f64>)> {
    let distance = |q: &[f64]| -> f64 { q.iter().zip(near).map(|(a, b)| (a - b) * (a - b)).sum() };
    labels
        .filter_map(adwi_robot::Configuration::from_bits)
        .filter_map(|c| {
            let posture = Posture {
                configuration: Some(c),
                turns: turns.to_vec(),
            };
            k.inverse(point, &posture, near)
                .filter(|q| holds(q))
                .map(|q| (c, q))
        })
        .min_by(|a, b| distance(&a.1).total_cmp(&distance(&b.1)))
}

/// The kinematics whose TCP is the table's point, and that point in the flange frame when
/// it is known.
fn kinematics(
    o: &CompensateOptions,
    table: &Table<AlignedBytes>,
    robot: Option<Robot>,
) -> Result<(Option<Kinematics>, Option<Isometry3<f64>>), Error> {
    let flag = o
        .table_tool
        .map(|t| kuka_pose([t[0], t[1], t[2]], [t[3], t[4], t[5]]));
    let iso =
        |t: &adwi_runtime::kinematics::Transform| adwi_robot::model::isometry_from_transform(t);
    let transform = |i: &Isometry3<f64>| adwi_robot::model::transform_from_isometry(i);
    let robot_error = |message: String| Error::Robot {
        path: o.robot.clone().unwrap_or_default(),
        message,
    };
    // The robot with the table's point as its tool.
    let placed = |robot: &Robot, table_tool: &Isometry3<f64>| {
        robot
            .with_parts(
                robot.name.clone(),
                robot.base(),
                transform(table_tool),
                robot.home().to_vec(),
            )
            .map_err(|e| robot_error(e.to_string()))
    };
    // Where the table records its point on the flange (format version 4 on).
    let recorded = table.header().evidence.point_in_flange.map(|p| {
        Isometry3::new(
            Vector3::from(p.translation_mm),
            Vector3::from(p.rotation_rad),
        )
    });
    match (table.model(), robot) {
        (None, None) => Ok((None, Some(flag.unwrap_or_else(Isometry3::identity)))),
        (None, Some(robot)) => {
            let table_tool = flag.unwrap_or_else(|| iso(&robot.tool()));
            let robot = placed(&robot, &table_tool)?;
            Ok((Some(Kinematics::new(robot)), Some(table_tool)))
        }
        (Some(model), robot) => {
            let chain = model.nominal();
            // The table's point in the frame the chain ends in.
            let point_in_end = iso(&chain.tool);
            let (robot, table_tool) = match robot {
                Some(robot) => {
                    if robot.joint_count() != chain.joint_count() {
                        return Err(robot_error(format!(
                            "{} joints, the table's robot {}",
                            robot.joint_count(),
                            chain.joint_count()
                        )));
                    }
                    // The table's point on the robot file's flange: the option's; else
                    // the table's chain's tool less the flange's place in the robot's last
                    // frame (its chain's tool less its own tool), exact where the two
                    // chains end in the same frame, or the point the table records in its
                    // flange (format version 4 on, to the digits it keeps), where they do
                    // not (a URDF's last joint against an MD-H file's flange). The first
                    // that makes the robot file the table's nominal robot is taken.
                    let flange_in_end = iso(&robot.chain().tool) * iso(&robot.tool()).inverse();
                    let candidates: Vec<Isometry3<f64>> = match flag {
                        Some(t) => vec![t],
                        None => [flange_in_end.inverse() * point_in_end]
                            .into_iter()
                            .chain(recorded)
                            .collect(),
                    };
                    let mut nearest: Option<(f64, f64)> = None;
                    let mut found = None;
                    for table_tool in candidates {
                        let placed = placed(&robot, &table_tool)?;
                        // The robot file must be the table's nominal robot.
                        let home = placed.home().to_vec();
                        let a = iso(&placed.chain().tcp_pose(&home).expect("one value per joint"));
                        let b = iso(&chain.tcp_pose(&home).expect("same joint count"));
                        let gap = (a.translation.vector - b.translation.vector).norm();
                        let turn = angle_between(
                            &a.rotation.to_rotation_matrix(),
                            &b.rotation.to_rotation_matrix(),
                        );
                        if gap <= 1e-6 && turn <= 1e-9 {
                            found = Some((placed, table_tool));
                            break;
                        }
                        if nearest.is_none_or(|(g, _)| gap < g) {
                            nearest = Some((gap, turn));
                        }
                    }
                    let Some((robot, table_tool)) = found else {
                        let (gap, turn) = nearest.unwrap_or((f64::NAN, f64::NAN));
                        return Err(robot_error(format!(
                            "it is not the table's nominal robot with the table's point as its tool: {gap:.6} mm and {:.6}° apart at home",
                            turn.to_degrees()
                        )));
                    };
                    (robot, Some(table_tool))
                }
                None => {
                    let joints = (0..chain.joint_count())
                        .map(|i| Joint {
                            name: format!("joint_{}", i + 1),
                            limits: [f64::NEG_INFINITY, f64::INFINITY],
                            inertial: None,
                            compliance_urad_per_nm: None,
                        })
                        .collect();
                    let robot = Robot::new(
                        "the table's nominal robot".into(),
                        Geometry::Chain(chain.joints().to_vec()),
                        joints,
                        chain.base,
                        chain.tool,
                        vec![0.0; chain.joint_count()],
                    )
                    .map_err(|e| {
                        Error::Option(format!("the table's nominal chain cannot be used: {e}"))
                    })?;
                    // Without a robot file the flange is where the table records its point
                    // on it, unless the option says.
                    (robot, flag.or(recorded))
                }
            };
            Ok((Some(Kinematics::new(robot)), table_tool))
        }
    }
}

/// What the motions using a corrected target do with it besides reaching it
/// ([`FrameUse::note`]), after the detail, once each.
fn say_notes(target: &crate::program::ProgramTarget, entry: &mut TargetLine) {
    if !entry.status.corrected() {
        return;
    }
    let mut said: Vec<&str> = Vec::new();
    for note in target.uses.iter().filter_map(|u| u.note.as_deref()) {
        if !said.contains(&note) {
            said.push(note);
        }
    }
    for note in said {
        entry.add_detail(note);
    }
}
