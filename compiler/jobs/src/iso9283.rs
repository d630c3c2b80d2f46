//! The ISO 9283 job: pose and distance characteristics of measured cycles, or the
//! standard's cube positions written as a plan to measure (`tablec iso9283`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use adwi_measure::iso9283::{
    characteristics_between, compensated, read_cycles, write_cube_plan, CycleRow, Iso9283Error,
    Report, ISO_CYCLES,
};
use adwi_measure::path::{self, read_command, read_stream, MeasuredPath, PathReport};
use adwi_output::OutputPlan;
use adwi_runtime::{Correction, Status};
use serde::Deserialize;

use crate::args::{parse_number_list, parse_triple};
use crate::inputs::{open_table, Inputs};
use crate::JobError;

/// ISO 9283 pose characteristics: every option of `tablec iso9283`.
#[derive(clap::Args, Deserialize, Debug, Clone)]
#[serde(default)]
pub struct Iso9283Args {
    /// Measured cycles (CSV: position, cycle, x, y, z, mx, my, mz, optionally a, b, c with
    /// ma, mb, mc; docs/measure.md).
    #[arg(value_name = "MEASUREMENTS.csv", required_unless_present_any = ["cube", "path"])]
    pub measurements: Option<PathBuf>,
    /// A tracker stream to reduce to the path characteristics instead (CSV: t, x, y, z,
    /// optionally path and cycle; docs/measure.md), with its commanded path (--command).
    #[arg(long, value_name = "STREAM.csv", requires = "command", conflicts_with_all = ["measurements", "cube"])]
    pub path: Option<PathBuf>,
    /// The commanded path(s) the stream ran (CSV: path, kind, x, y, z, vx, vy, vz, speed;
    /// `--cube ... --path-plan` writes one).
    #[arg(long, value_name = "PATH.csv", requires = "path")]
    pub command: Option<PathBuf>,
    /// With --cube: write the standard's test paths in the cube (line, circles, rectangle)
    /// as a command file (--output) instead of the pose plan.
    #[arg(long, requires = "cube")]
    pub path_plan: bool,
    /// The test paths' commanded speed, mm/s (with --path-plan).
    #[arg(
        long,
        value_name = "MM_PER_S",
        default_value_t = 100.0,
        requires = "path_plan"
    )]
    pub speed: f64,
    /// Write the five ISO 9283 positions of a cube instead: its centre and edge length,
    /// X,Y,Z,SIDE (mm, base frame), as a plan CSV (--output).
    #[arg(long, value_name = "X,Y,Z,SIDE", value_parser = parse_cube, allow_hyphen_values = true,
          conflicts_with_all = ["measurements", "json", "table", "report"], requires = "output")]
    #[serde(deserialize_with = "cube")]
    pub cube: Option<[f64; 4]>,
    /// The plan's tool orientation A,B,C (KUKA degrees, R = Rz(A)·Ry(B)·Rx(C); the
    /// standard's a, b, c about x, y, z are C, B, A). The default tilts the tool 45° from
    /// pointing down, away from the gimbal lock at B = ±90° where a and c are undefined.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, default_value = "0,45,0")]
    pub abc: [f64; 3],
    /// Cycles the plan repeats the five positions (ISO 9283 asks for 30).
    #[arg(long, default_value_t = ISO_CYCLES)]
    pub cycles: u32,
    /// The plan CSV to write (with --cube).
    #[arg(long, short, value_name = "PLAN.csv")]
    pub output: Option<PathBuf>,
    /// A pair of positions whose distance accuracy and repeatability to compute,
    /// FROM,TO (repeatable; default the standard's P2,P4).
    #[arg(long = "distance", value_name = "FROM,TO", value_parser = parse_pair)]
    #[serde(deserialize_with = "pairs")]
    pub distance: Vec<(String, String)>,
    /// Also write the characteristics as JSON.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Also report the characteristics the table's compensation would give on these
    /// cycles: each attained pose less the table's predicted error at its commanded pose
    /// (a first-order prediction; docs/measure.md says what it can claim).
    #[arg(long, value_name = "TABLE")]
    pub table: Option<PathBuf>,
    /// Also write the characteristics as an HTML page, DIR/index.html (with --table, as
    /// measured and as compensated side by side).
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

impl Default for Iso9283Args {
    fn default() -> Iso9283Args {
        Iso9283Args {
            measurements: None,
            path: None,
            command: None,
            path_plan: false,
            speed: 100.0,
            cube: None,
            abc: [0.0, 45.0, 0.0],
            cycles: ISO_CYCLES,
            output: None,
            distance: Vec::new(),
            json: None,
            table: None,
            report: None,
        }
    }
}

/// `X,Y,Z,SIDE` in one argument.
fn parse_cube(text: &str) -> Result<[f64; 4], String> {
    let values = parse_number_list(text)?;
    cube_of(values)
}

fn cube_of(values: Vec<f64>) -> Result<[f64; 4], String> {
    values.try_into().map_err(|v: Vec<f64>| {
        format!(
            "four numbers are needed, the centre X,Y,Z and the SIDE; {} given",
            v.len()
        )
    })
}

/// `FROM,TO`: two position names.
fn parse_pair(text: &str) -> Result<(String, String), String> {
    match text.split(',').map(str::trim).collect::<Vec<_>>()[..] {
        [from, to] if !from.is_empty() && !to.is_empty() && from != to => {
            Ok((from.to_string(), to.to_string()))
        }
        _ => Err(format!(
            "'{text}': give two different position names, FROM,TO (P2,P4, say)"
        )),
    }
}

/// Pairs from Python's `distance=["P2,P4", ...]`.
fn pairs<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<(String, String)>, D::Error> {
    let texts: Vec<String> = Vec::deserialize(d)?;
    texts
        .iter()
        .map(|t| parse_pair(t).map_err(serde::de::Error::custom))
        .collect()
}

/// A cube from a list of four numbers (Python's `cube=[...]`).
fn cube<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<[f64; 4]>, D::Error> {
    let values: Option<Vec<f64>> = Option::deserialize(d)?;
    values
        .map(|v| cube_of(v).map_err(serde::de::Error::custom))
        .transpose()
}

/// The command line that reduces these cycles, as the report page quotes it.
fn command_line(args: &Iso9283Args) -> String {
    let mut line = String::from("tablec iso9283");
    if let Some(m) = &args.measurements {
        line += &format!(" {}", m.display());
    }
    if let (Some(p), Some(c)) = (&args.path, &args.command) {
        line += &format!(" --path {} --command {}", p.display(), c.display());
    }
    if let Some(t) = &args.table {
        line += &format!(" --table {}", t.display());
    }
    if let Some(r) = &args.report {
        line += &format!(" --report {}", r.display());
    }
    line
}

/// What to do, checked.
enum Work {
    /// Reduce measured cycles, and with a table their compensation.
    Report {
        rows: Vec<CycleRow>,
        table: OpenTable,
    },
    /// Reduce a tracker stream, and with a table its compensation.
    Path {
        paths: Vec<MeasuredPath>,
        table: OpenTable,
    },
    /// Write a cube plan (poses or paths).
    Plan { text: String },
}

/// An ISO 9283 job checked and loaded, ready to run.
pub struct Iso9283Job {
    args: Iso9283Args,
    work: Work,
    outputs: OutputPlan,
}

/// What an ISO 9283 job found, and what it wrote.
#[derive(Debug, Clone)]
pub struct Iso9283Result {
    /// The characteristics of the measured cycles (none for a plan).
    pub report: Option<Report>,
    /// Those of the cycles as the table's compensation would attain them.
    pub compensated: Option<Report>,
    /// The path characteristics of a tracker stream (with --path).
    pub path: Option<PathReport>,
    /// Those of the stream as the table's compensation would attain it.
    pub path_compensated: Option<PathReport>,
    /// The files written.
    pub written: Vec<PathBuf>,
    /// Whether the plan written is the standard's test paths (`--path-plan`) rather than
    /// its cube positions.
    pub path_plan: bool,
}

impl Iso9283Result {
    /// What `tablec iso9283` prints: the characteristics as a table per position and per
    /// distance (or per path, corner and velocity), measured then compensated; or what a
    /// plan holds; then the files written.
    pub fn text(&self) -> String {
        let mut out = String::new();
        if let Some(report) = &self.report {
            report_text(&mut out, report);
        }
        if let Some(report) = &self.compensated {
            out.push_str(
                "\ncompensated by the table (each attained pose less the predicted error at its \
                 command):\n",
            );
            report_text(&mut out, report);
        }
        if let Some(report) = &self.path {
            path_text(&mut out, report);
        }
        if let Some(report) = &self.path_compensated {
            out.push_str(
                "\ncompensated by the table (each point less the predicted error at its \
                 commanded point):\n",
            );
            path_text(&mut out, report);
        }
        if self.report.is_none() && self.path.is_none() {
            out.push_str(if self.path_plan {
                "plan           paths line (P2 to P4), circle and small_circle (about P1), \
                 rectangle (P2, P3, P4, P5); a, b, c are KUKA A, B, C degrees, \
                 R = Rz(a)·Ry(b)·Rx(c)\n"
            } else {
                "plan           each cycle P1, P5, P4, P3, P2 (ISO 9283); a, b, c are KUKA A, B, \
                 C degrees, R = Rz(a)·Ry(b)·Rx(c) (the standard's a, b, c about x, y, z are c, \
                 b, a)\n"
            });
        }
        for path in &self.written {
            let _ = writeln!(out, "wrote          {}", path.display());
        }
        out
    }
}

/// Per path AT and RT, per corner CR and CO, and the velocity figures.
fn path_text(out: &mut String, report: &PathReport) {
    let _ = writeln!(
        out,
        "{:<14} {:>4} {:>10} {:>6} {:>9} {:>9} {:>9}",
        "path", "n", "length mm", "planes", "AT_P mm", "mean AT", "RT_P mm"
    );
    for p in &report.paths {
        let _ = writeln!(
            out,
            "{:<14} {:>4} {:>10.3} {:>6} {:>9.4} {:>9.4} {:>9.4}",
            p.name, p.n, p.length_mm, p.planes, p.at_p_mm, p.at_mean_mm, p.rt_p_mm
        );
    }
    if report.paths.iter().any(|p| !p.corners.is_empty()) {
        let _ = writeln!(
            out,
            "{:<14} {:>6} {:>9} {:>9} {:>9} {:>9}",
            "corner", "", "CR mm", "CR max", "CO mm", "CO max"
        );
        for p in &report.paths {
            for c in &p.corners {
                let _ = writeln!(
                    out,
                    "{:<14} {:>6} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
                    p.name, c.corner, c.cr_mm, c.cr_max_mm, c.co_mm, c.co_max_mm
                );
            }
        }
    }
    if report.paths.iter().any(|p| p.velocity.is_some()) {
        let _ = writeln!(
            out,
            "{:<14} {:>10} {:>10} {:>9} {:>9} {:>9}",
            "velocity", "v_c mm/s", "mean mm/s", "AV %", "RV ±%", "FV mm/s"
        );
        for p in &report.paths {
            if let Some(v) = &p.velocity {
                let _ = writeln!(
                    out,
                    "{:<14} {:>10.3} {:>10.4} {:>9.4} {:>9.4} {:>9.4}",
                    p.name, v.commanded_mm_s, v.mean_mm_s, v.av_percent, v.rv_percent, v.fv_mm_s
                );
            }
        }
    }
    for note in &report.notes {
        let _ = writeln!(out, "note           {note}");
    }
}

/// Per position AP and RP (mm; orientation degrees when measured), then AD and RD.
fn report_text(out: &mut String, report: &Report) {
    let oriented = report.positions.iter().any(|p| p.ap_a_deg.is_some());
    let _ = write!(
        out,
        "{:<10} {:>4} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "position", "n", "AP_P mm", "AP_x mm", "AP_y mm", "AP_z mm", "RP_l mm"
    );
    if oriented {
        let _ = write!(
            out,
            " {:>8} {:>8} {:>8} {:>9} {:>9} {:>9}",
            "AP_a °", "AP_b °", "AP_c °", "RP_a ±°", "RP_b ±°", "RP_c ±°"
        );
    }
    out.push('\n');
    for p in &report.positions {
        let _ = write!(
            out,
            "{:<10} {:>4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
            p.name, p.n, p.ap_p_mm, p.ap_x_mm, p.ap_y_mm, p.ap_z_mm, p.rp_l_mm
        );
        let angles = [
            p.ap_a_deg, p.ap_b_deg, p.ap_c_deg, p.rp_a_deg, p.rp_b_deg, p.rp_c_deg,
        ];
        if let [Some(a), Some(b), Some(c), Some(ra), Some(rb), Some(rc)] = angles {
            let _ = write!(
                out,
                " {a:>8.4} {b:>8.4} {c:>8.4} {ra:>9.4} {rb:>9.4} {rc:>9.4}"
            );
        }
        out.push('\n');
    }
    if !report.distance.is_empty() {
        let _ = writeln!(
            out,
            "{:<21} {:>4} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9}",
            "distance", "n", "D_c mm", "AD_P mm", "AD_x mm", "AD_y mm", "AD_z mm", "RD ±mm"
        );
        for d in &report.distance {
            let _ = writeln!(
                out,
                "{:<21} {:>4} {:>10.3} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
                format!("{} - {}", d.from, d.to),
                d.n,
                d.commanded_mm,
                d.ad_p_mm,
                d.ad_x_mm,
                d.ad_y_mm,
                d.ad_z_mm,
                d.rd_mm
            );
        }
    }
    let fewest = report.positions.iter().map(|p| p.n).min().unwrap_or(0);
    if fewest < ISO_CYCLES as usize {
        let _ = writeln!(
            out,
            "note           {fewest} cycles at the fewest: ISO 9283 asks for {ISO_CYCLES}"
        );
    }
    if let Some(convention) = report.orientation_convention {
        let _ = writeln!(out, "orientation    {convention}");
    }
    for note in &report.notes {
        let _ = writeln!(out, "note           {note}");
    }
}

fn measure_error(e: Iso9283Error) -> JobError {
    JobError::Measure(Box::new(e))
}

fn path_error(e: path::PathError) -> JobError {
    JobError::Measure(Box::new(Iso9283Error::Path(e)))
}

/// The path report, unless a figure came out non-finite.
fn finite_path(report: PathReport) -> Result<PathReport, JobError> {
    let json = serde_json::to_value(&report).map_err(|e| JobError::NonFinite(e.to_string()))?;
    fn all_finite(v: &serde_json::Value) -> bool {
        match v {
            serde_json::Value::Null => false,
            serde_json::Value::Array(a) => a.iter().all(all_finite),
            serde_json::Value::Object(o) => o
                .iter()
                .all(|(k, v)| (k == "velocity" && v.is_null()) || all_finite(v)),
            _ => true,
        }
    }
    if all_finite(&json) {
        Ok(report)
    } else {
        Err(JobError::NonFinite(
            "an ISO 9283 path characteristic came out non-finite: the stream holds implausible \
             coordinates"
                .into(),
        ))
    }
}

/// The report, unless a characteristic came out non-finite (coordinates near the largest
/// floating-point numbers), which is never reported as a result.
fn finite(report: Report) -> Result<Report, JobError> {
    let positions = report.positions.iter().all(|p| {
        [p.ap_p_mm, p.rp_l_mm, p.ap_x_mm, p.ap_y_mm, p.ap_z_mm]
            .into_iter()
            .chain(
                [
                    p.ap_a_deg, p.ap_b_deg, p.ap_c_deg, p.rp_a_deg, p.rp_b_deg, p.rp_c_deg,
                ]
                .into_iter()
                .flatten(),
            )
            .all(f64::is_finite)
    });
    let distances = report.distance.iter().all(|d| {
        [d.ad_p_mm, d.ad_x_mm, d.ad_y_mm, d.ad_z_mm, d.rd_mm]
            .iter()
            .all(|v| v.is_finite())
    });
    if positions && distances {
        Ok(report)
    } else {
        Err(JobError::NonFinite(
            "an ISO 9283 characteristic came out non-finite: the cycles hold implausible \
             coordinates"
                .into(),
        ))
    }
}

/// The test paths' options: a path plan needs a cube, and its speed is a speed.
fn check_path_plan_options(args: &Iso9283Args) -> Result<(), JobError> {
    if args.path_plan && args.cube.is_none() {
        return Err(JobError::option(
            "path-plan",
            "writes the test paths of a cube: give --cube",
        ));
    }
    if args.speed != 100.0 && !args.path_plan {
        return Err(JobError::option(
            "speed",
            "is the test paths' speed: give it with --cube ... --path-plan",
        ));
    }
    if !(args.speed > 0.0 && args.speed <= 1e6) {
        return Err(JobError::option(
            "speed",
            format!("{} mm/s: give a speed above 0 mm/s", args.speed),
        ));
    }
    Ok(())
}

/// The JSON and the report page checked against `inputs`.
fn report_outputs(args: &Iso9283Args, inputs: &Inputs) -> Result<OutputPlan, JobError> {
    let mut outputs = OutputPlan::check(
        &args
            .json
            .iter()
            .map(PathBuf::as_path)
            .collect::<Vec<&Path>>(),
        &inputs.paths(),
    )?;
    if let Some(dir) = &args.report {
        outputs.check_in_new_directory(&dir.join("index.html"), &inputs.paths())?;
    }
    Ok(outputs)
}

/// The table to compensate by, open, with its path.
type OpenTable = Option<Box<(PathBuf, adwi_runtime::Table<memmap2::Mmap>)>>;

/// Opens the table of `--table`, if given.
fn open_compensation(args: &Iso9283Args) -> Result<OpenTable, JobError> {
    match &args.table {
        Some(t) => Ok(Some(Box::new((t.clone(), open_table(t)?)))),
        None => Ok(None),
    }
}

/// A tracker stream and its commanded paths, read; the outputs checked first.
fn path_work(
    args: &Iso9283Args,
    stream: &Path,
    command: &Path,
) -> Result<(Work, OutputPlan), JobError> {
    if args.measurements.is_some() || args.cube.is_some() {
        return Err(JobError::Options(
            "--path reduces a tracker stream: measured cycles and --cube are other \
             tests, one at a time"
                .into(),
        ));
    }
    let plan_only = Iso9283Args::default();
    if args.cycles != plan_only.cycles
        || args.abc != plan_only.abc
        || !args.distance.is_empty()
        || args.output.is_some()
    {
        return Err(JobError::Options(
            "--cycles, --abc, --distance and --output are for pose cycles and plans; \
             --path reports to standard output, --json and --report"
                .into(),
        ));
    }
    let mut inputs = Inputs::default();
    inputs.add(stream);
    inputs.add(command);
    if let Some(t) = &args.table {
        inputs.add(t);
    }
    let outputs = report_outputs(args, &inputs)?;
    let commands = read_command(command).map_err(path_error)?;
    let stream = read_stream(stream).map_err(path_error)?;
    let paths = path::measured_paths(&stream, &commands).map_err(path_error)?;
    let table = open_compensation(args)?;
    Ok((Work::Path { paths, table }, outputs))
}

/// A cube's plan (its poses, or its test paths), computed; its output checked.
fn plan_work(
    args: &Iso9283Args,
    [x, y, z, side]: [f64; 4],
) -> Result<(Work, OutputPlan), JobError> {
    if args.json.is_some()
        || args.table.is_some()
        || args.report.is_some()
        || !args.distance.is_empty()
    {
        return Err(JobError::Options(
            "--cube writes a plan: --json, --table, --report and --distance report \
             on measured cycles"
                .into(),
        ));
    }
    let Some(output) = &args.output else {
        return Err(JobError::option(
            "output",
            "--cube writes its plan there: give it",
        ));
    };
    if args.path_plan && args.cycles != ISO_CYCLES {
        return Err(JobError::option(
            "cycles",
            "repeats the pose plan; a path plan is run as many times as the test asks",
        ));
    }
    let text = if args.path_plan {
        adwi_measure::iso9283::write_path_plan([x, y, z], side, args.abc, args.speed)
    } else {
        write_cube_plan([x, y, z], side, args.abc, args.cycles)
    }
    .map_err(|e| JobError::option("cube", e))?;
    Ok((Work::Plan { text }, OutputPlan::check(&[output], &[])?))
}

/// Measured cycles, read, and the table to compensate them by; the outputs checked first.
fn report_work(args: &Iso9283Args, cycles: &Path) -> Result<(Work, OutputPlan), JobError> {
    let plan_only = Iso9283Args::default();
    if args.cycles != plan_only.cycles || args.abc != plan_only.abc {
        return Err(JobError::Options(
            "--cycles and --abc shape a cube's plan (--cube); measured cycles carry \
             their own"
                .into(),
        ));
    }
    if args.output.is_some() {
        return Err(JobError::option(
            "output",
            "writes a cube's plan (--cube); the report goes to standard output and \
             --json",
        ));
    }
    let mut inputs = Inputs::default();
    inputs.add(cycles);
    if let Some(t) = &args.table {
        inputs.add(t);
    }
    let outputs = report_outputs(args, &inputs)?;
    let rows = read_cycles(cycles).map_err(measure_error)?;
    let table = open_compensation(args)?;
    Ok((Work::Report { rows, table }, outputs))
}

impl Iso9283Job {
    /// Checks `args`, reads the cycles and opens the table, or computes the plan; checks
    /// the outputs.
    ///
    /// # Errors
    ///
    /// A refused option or combination, an unreadable input, an output that is an input.
    pub fn new(args: Iso9283Args) -> Result<Iso9283Job, JobError> {
        check_path_plan_options(&args)?;
        let (work, outputs) = match (&args.path, &args.command, &args.measurements, args.cube) {
            (Some(stream), Some(command), _, _) => path_work(&args, stream, command)?,
            (None, None, Some(_), Some(_)) | (None, None, None, None) => {
                return Err(JobError::Options(
                    "give the measured cycles (MEASUREMENTS.csv), a tracker stream (--path) or a \
                     cube to plan (--cube), one of them"
                        .into(),
                ))
            }
            (None, None, None, Some(cube)) => plan_work(&args, cube)?,
            (None, None, Some(cycles), None) => report_work(&args, cycles)?,
            _ => {
                return Err(JobError::Options(
                    "--path (the tracker stream) and --command (the commanded path) go together"
                        .into(),
                ))
            }
        };
        Ok(Iso9283Job {
            args,
            work,
            outputs,
        })
    }

    /// Reduces the cycles (and their compensation) or writes the plan.
    ///
    /// # Errors
    ///
    /// Cycles the standard cannot reduce (a position commanded twice, too few cycles), a
    /// commanded pose the table gives no correction for, a write failing.
    pub fn run(self) -> Result<Iso9283Result, JobError> {
        let Iso9283Job {
            args,
            work,
            outputs,
        } = self;
        match work {
            Work::Plan { text } => {
                let output = args.output.expect("checked");
                outputs.write(&[(&output, text.as_bytes())])?;
                Ok(Iso9283Result {
                    report: None,
                    compensated: None,
                    path: None,
                    path_compensated: None,
                    written: vec![output],
                    path_plan: args.path_plan,
                })
            }
            Work::Path { paths, table } => {
                let report = finite_path(path::characteristics(&paths).map_err(path_error)?)?;
                let compensated = match table.as_deref() {
                    Some((tpath, table)) => {
                        let paths = path::compensated(&paths, |c| {
                            correction(tpath, table, c, "a tracker stream does not carry", "point")
                                .map(|q| q.position_error_mm)
                        })
                        .map_err(path_error)?;
                        Some(finite_path(
                            path::characteristics(&paths).map_err(path_error)?,
                        )?)
                    }
                    None => None,
                };
                let written = write_reduction(
                    &args,
                    &outputs,
                    || {
                        serde_json::json!({
                            "paths": report.paths,
                            "notes": report.notes,
                            "compensated": compensated,
                        })
                    },
                    || {
                        adwi_eval::report::iso9283::path_html(
                            &report,
                            compensated.as_ref(),
                            &command_line(&args),
                        )
                    },
                )?;
                Ok(Iso9283Result {
                    report: None,
                    compensated: None,
                    path: Some(report),
                    path_compensated: compensated,
                    written,
                    path_plan: false,
                })
            }
            Work::Report { rows, table } => {
                let reduce = |rows: &[CycleRow]| {
                    characteristics_between(rows, &args.distance).map_err(measure_error)
                };
                let report = finite(reduce(&rows)?)?;
                let compensated = match table.as_deref() {
                    Some((path, table)) => {
                        let rows = compensated(&rows, |row| {
                            correction(
                                path,
                                table,
                                row.commanded_mm,
                                "cycles do not carry",
                                "position",
                            )
                            .map(|c| (c.position_error_mm, c.orientation_error_rad))
                        })
                        .map_err(measure_error)?;
                        Some(finite(reduce(&rows)?)?)
                    }
                    None => None,
                };
                let written = write_reduction(
                    &args,
                    &outputs,
                    || {
                        serde_json::json!({
                            "positions": report.positions,
                            "distance": report.distance,
                            "orientation_convention": report.orientation_convention,
                            "notes": report.notes,
                            "compensated": compensated,
                        })
                    },
                    || {
                        adwi_eval::report::iso9283::html(
                            &report,
                            compensated.as_ref(),
                            &command_line(&args),
                        )
                    },
                )?;
                Ok(Iso9283Result {
                    report: Some(report),
                    compensated,
                    path: None,
                    path_compensated: None,
                    written,
                    path_plan: false,
                })
            }
        }
    }
}

/// The table's correction at a commanded position (mm), or why it gives none: `lacking`
/// says what carries the positions without joints (a hybrid table needs them), `what` the
/// kind of position.
fn correction(
    path: &Path,
    table: &adwi_runtime::Table<memmap2::Mmap>,
    commanded_mm: [f64; 3],
    lacking: &str,
    what: &str,
) -> Result<Correction, String> {
    let c = table.query(commanded_mm);
    match c.status {
        Status::Ok => Ok(c),
        Status::MissingJoints => Err(format!(
            "{} is a hybrid table: its correction needs joint values, which {lacking}",
            path.display()
        )),
        s => Err(format!(
            "{} gives no correction at the commanded {what} {commanded_mm:?} mm: {}",
            path.display(),
            s.as_str()
        )),
    }
}

/// Writes a reduction's `--json` and `--report` page, whichever were asked for, together
/// (none is written if one fails); the files written.
fn write_reduction(
    args: &Iso9283Args,
    outputs: &OutputPlan,
    json: impl FnOnce() -> serde_json::Value,
    page: impl FnOnce() -> String,
) -> Result<Vec<PathBuf>, JobError> {
    let mut contents: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&json())
            .map_err(|e| JobError::NonFinite(e.to_string()))?;
        contents.push((path.clone(), text.into_bytes()));
    }
    if let Some(dir) = &args.report {
        contents.push((dir.join("index.html"), page().into_bytes()));
    }
    let borrowed: Vec<(&Path, &[u8])> = contents
        .iter()
        .map(|(p, b)| (p.as_path(), &b[..]))
        .collect();
    outputs.write(&borrowed)?;
    Ok(contents.into_iter().map(|(p, _)| p).collect())
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use serde::de::value::{Error, MapDeserializer};

    use super::*;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: Iso9283Args,
    }

    /// clap's defaults are the struct's `Default`, which Python's keywords start from.
    #[test]
    fn the_command_line_and_python_have_the_same_defaults() {
        let parsed = Cli::parse_from(["iso9283", "m.csv"]).args;
        let mut expected = Iso9283Args::deserialize(MapDeserializer::<_, Error>::new(
            std::iter::empty::<(&str, &str)>(),
        ))
        .unwrap();
        expected.measurements = Some("m.csv".into());
        assert_eq!(format!("{parsed:?}"), format!("{expected:?}"));
        let default = Iso9283Args {
            measurements: Some("m.csv".into()),
            ..Iso9283Args::default()
        };
        assert_eq!(format!("{parsed:?}"), format!("{default:?}"));
    }

    /// A cube's plan, measured, reduced through the job; JSON written with the keys the
    /// documentation names.
    #[test]
    fn a_plan_measured_is_reported_and_written_as_json() {
        let dir = tempfile::tempdir().unwrap();
        let plan = dir.path().join("plan.csv");
        Iso9283Job::new(Iso9283Args {
            cube: Some([1000.0, 0.0, 800.0, 300.0]),
            cycles: 3,
            output: Some(plan.clone()),
            ..Iso9283Args::default()
        })
        .unwrap()
        .run()
        .unwrap();
        // Every attained position 0.1 mm above its command, and 0.01 mm further in x
        // each cycle.
        let text = std::fs::read_to_string(&plan).unwrap();
        let mut measured = String::from("position,cycle,x,y,z,mx,my,mz\n");
        for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let v: Vec<f64> = f[1..5].iter().map(|t| t.parse().unwrap()).collect();
            let (cycle, x, y, z) = (v[0], v[1], v[2], v[3]);
            measured.push_str(&format!(
                "{},{cycle},{x},{y},{z},{},{y},{}\n",
                f[0],
                x + 0.01 * cycle,
                z + 0.1
            ));
        }
        let cycles = dir.path().join("cycles.csv");
        std::fs::write(&cycles, measured).unwrap();
        let json = dir.path().join("r.json");
        let report_dir = dir.path().join("report");
        let result = Iso9283Job::new(Iso9283Args {
            measurements: Some(cycles.clone()),
            json: Some(json.clone()),
            report: Some(report_dir.clone()),
            ..Iso9283Args::default()
        })
        .unwrap()
        .run()
        .unwrap();
        let report = result.report.unwrap();
        assert_eq!(report.positions.len(), 5);
        for p in &report.positions {
            // x̄ − x_c = 0.02, z̄ − z_c = 0.1.
            assert!((p.ap_x_mm - 0.02).abs() < 1e-9 && (p.ap_z_mm - 0.1).abs() < 1e-9);
            assert!((p.ap_p_mm - (0.02f64.powi(2) + 0.01).sqrt()).abs() < 1e-9);
        }
        let written: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(written["positions"][0]["name"], "P1");
        assert_eq!(written["positions"][0]["n"], 3);
        assert!(written["positions"][0]["rp_l_mm"].is_number());
        // The standard's distance pair, P2 and P4.
        assert_eq!(written["distance"].as_array().unwrap().len(), 1);
        assert_eq!(written["distance"][0]["from"], "P2");
        assert_eq!(written["distance"][0]["to"], "P4");
        // The page, written with the JSON, holds its figures.
        assert_eq!(
            result.written,
            vec![json.clone(), report_dir.join("index.html")]
        );
        let page = std::fs::read_to_string(report_dir.join("index.html")).unwrap();
        for p in written["positions"].as_array().unwrap() {
            for key in ["ap_p_mm", "rp_l_mm"] {
                let v = p[key].as_f64().unwrap();
                assert!(page.contains(&format!("<td>{v:.4}</td>")), "{key} {v}");
            }
        }

        // The plan's output is refused with measurements, the measurements as output too.
        let e = Iso9283Job::new(Iso9283Args {
            measurements: Some(cycles.clone()),
            output: Some(dir.path().join("x.csv")),
            ..Iso9283Args::default()
        })
        .err()
        .unwrap();
        assert!(matches!(e, JobError::Options(_)), "{e}");
        let e = Iso9283Job::new(Iso9283Args {
            measurements: Some(cycles.clone()),
            json: Some(cycles),
            ..Iso9283Args::default()
        })
        .err()
        .unwrap();
        assert!(matches!(e, JobError::Output(_)), "{e}");
    }
}
