//! `query`: the correction a table gives at one target or at every row of a targets file,
//! and the command that lands on it.
//!
//! tablec and the Python package both answer a target through [`answer`], so a target's
//! correction, its command and the fixed point's tolerance are decided in one place.

use std::io::Write;
use std::path::PathBuf;

use adwi_output::{write_atomically, OutputPlan};
use adwi_runtime::chain::JointKind;
use adwi_runtime::{Correction, Status, Table, Target, Tier};
use adwi_samples::pose;
use memmap2::Mmap;

use crate::{args, JobError, Reading};

pub use adwi_runtime::{COMPENSATE_ITERATIONS, COMPENSATE_TOLERANCE_MM};

/// How the command for a target is found.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FixedPoint {
    /// Stop once the predicted landing is within this of the target, mm.
    pub tolerance_mm: f64,
    /// At most this many corrections of the command.
    pub max_iterations: u32,
}

impl Default for FixedPoint {
    fn default() -> FixedPoint {
        FixedPoint {
            tolerance_mm: COMPENSATE_TOLERANCE_MM,
            max_iterations: COMPENSATE_ITERATIONS,
        }
    }
}

impl FixedPoint {
    /// A fixed point with a positive, finite tolerance and at least one iteration.
    ///
    /// # Errors
    ///
    /// [`JobError::Options`] naming the value refused.
    pub fn new(tolerance_mm: f64, max_iterations: u32) -> Result<FixedPoint, JobError> {
        if !(tolerance_mm.is_finite() && tolerance_mm > 0.0) {
            return Err(JobError::option(
                "tolerance_mm",
                format!("{tolerance_mm} is not a positive number of millimetres"),
            ));
        }
        if max_iterations == 0 {
            return Err(JobError::option(
                "max_iterations",
                "0: the command needs at least one iteration",
            ));
        }
        Ok(FixedPoint {
            tolerance_mm,
            max_iterations,
        })
    }
}

/// How a command was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CommandStatus {
    /// The fixed point `command + error(command) = target` was reached.
    Converged,
    /// The iteration bound was reached first.
    NotConverged,
    /// `target − error`: with joint angles, the moved command's own joints are only known
    /// to the controller's inverse kinematics, so no fixed point is sought.
    FirstOrder,
}

impl CommandStatus {
    /// Every status, in the order of their codes.
    pub const ALL: [CommandStatus; 3] = [
        CommandStatus::Converged,
        CommandStatus::NotConverged,
        CommandStatus::FirstOrder,
    ];

    /// The name the CSV's `command_status` column and the JSON use.
    pub const fn as_str(self) -> &'static str {
        match self {
            CommandStatus::Converged => "converged",
            CommandStatus::NotConverged => "not_converged",
            CommandStatus::FirstOrder => "first_order",
        }
    }

    /// The code the Python package's arrays carry.
    pub const fn code(self) -> u8 {
        self as u8
    }
}

/// The pose to command so that the robot lands on the target.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Command {
    /// The position to command, mm, base frame.
    pub position_mm: [f64; 3],
    /// The rotation vector to apply to the target's orientation, rad, base frame.
    pub rotation_rad: [f64; 3],
    /// How it was found.
    pub status: CommandStatus,
    /// Corrections made (0 for a first-order command).
    pub iterations: u32,
    /// The predicted distance from the target at the last iteration, mm; `None` for a
    /// first-order command.
    pub fixed_point_residual_mm: Option<f64>,
}

impl Command {
    /// How the command was found, in words.
    pub fn how(&self) -> String {
        match self.fixed_point_residual_mm {
            None => "first order: target − error".to_string(),
            Some(residual_mm) => format!(
                "{} after {} iterations, residual {residual_mm:.2e} mm",
                self.status.as_str().replace('_', " "),
                self.iterations
            ),
        }
    }
}

/// The tier `exact` asks for.
fn tier(exact: bool) -> Tier {
    if exact {
        Tier::Exact
    } else {
        Tier::Served
    }
}

/// A target's correction and, when `fixed_point` asks for it and the table answered, the
/// command that lands on it: the fixed point of `command + error(command) = target`
/// ([`Table::compensate`]); with joint angles, the first-order `target − error`.
pub fn answer<D: AsRef<[u8]>>(
    table: &Table<D>,
    target: &Target,
    joints_rad: Option<&[f64]>,
    exact: bool,
    fixed_point: Option<FixedPoint>,
) -> (Correction, Option<Command>) {
    let c = table.answer(target, joints_rad, tier(exact));
    let Some(fixed_point) = fixed_point.filter(|_| c.status == Status::Ok) else {
        return (c, None);
    };
    if joints_rad.is_some() {
        let e = c.position_error_mm;
        let command = Command {
            position_mm: [0, 1, 2].map(|a| target.position_mm[a] - e[a]),
            rotation_rad: c.orientation_error_rad.map(|v| -v),
            status: CommandStatus::FirstOrder,
            iterations: 0,
            fixed_point_residual_mm: None,
        };
        return (c, Some(command));
    }
    let FixedPoint {
        tolerance_mm,
        max_iterations,
    } = fixed_point;
    let comp = if exact {
        table
            .exact()
            .compensate(target, tolerance_mm, max_iterations)
    } else {
        table.compensate(target, tolerance_mm, max_iterations)
    };
    let command = Command {
        position_mm: comp.command_position_mm,
        rotation_rad: comp.command_rotation_rad,
        status: if comp.converged {
            CommandStatus::Converged
        } else {
            CommandStatus::NotConverged
        },
        iterations: comp.iterations,
        fixed_point_residual_mm: Some(comp.residual_mm),
    };
    (c, Some(command))
}

/// What a query asks.
#[derive(Clone, Debug, Default)]
pub struct QueryArgs {
    /// The table.
    pub table: PathBuf,
    /// One target: X Y Z (mm, base frame), optionally A B C (KUKA degrees).
    pub pose: Vec<f64>,
    /// The target's inverse-kinematics configuration.
    pub config: Option<u8>,
    /// The joint values the controller will use for the one target, degrees (mm for
    /// prismatic joints).
    pub joints_deg: Option<Vec<f64>>,
    /// The TCP the targets are for, X,Y,Z mm in the flange frame.
    pub tcp_mm: Option<Vec<f64>>,
    /// A CSV of targets instead of one pose.
    pub targets: Option<PathBuf>,
    /// How the targets CSV is read.
    pub reading: Reading,
    /// Where the answers to `targets` go, as CSV; `None`: the caller prints them.
    pub output: Option<PathBuf>,
    /// Answer from the exact tier instead of the served field.
    pub exact: bool,
}

/// One target of a query: checked, with its joints in radians.
#[derive(Clone, Debug)]
struct OneTarget {
    target: Target,
    abc_deg: Option<[f64; 3]>,
    joints_rad: Option<Vec<f64>>,
}

/// What a query asks, its options checked, before the table is opened.
enum Asked<'a> {
    One(OneTarget),
    File(
        &'a std::path::Path,
        adwi_samples::ColumnMap,
        adwi_samples::ReadOptions,
    ),
}

enum Work {
    One(OneTarget),
    File {
        rows: Vec<adwi_samples::TargetRow>,
        output: Option<PathBuf>,
    },
}

/// A query whose options and inputs have all been checked: [`QueryJob::run`] only answers.
pub struct QueryJob {
    table: Table<Mmap>,
    exact: bool,
    tcp_mm: Option<[f64; 3]>,
    work: Work,
}

impl QueryJob {
    /// Checks every option, then opens the table and reads the targets.
    ///
    /// # Errors
    ///
    /// [`JobError::Options`] for a pose that is not X Y Z or X Y Z A B C, a value beyond any
    /// robot's range, a `tcp` that is not three coordinates, joint values the table's robot
    /// does not take, or options that exclude each other; [`JobError::Table`] for a table
    /// that cannot be opened; [`JobError::Read`] for an unreadable targets file;
    /// [`JobError::Output`] for an output that names an input.
    pub fn new(args: QueryArgs) -> Result<QueryJob, JobError> {
        let tcp_mm = tcp_of(args.tcp_mm.as_deref())?;
        let asked = match &args.targets {
            Some(targets) => {
                if !args.pose.is_empty() {
                    return Err(JobError::Options(
                        "give one target (X Y Z [A B C]) or --targets FILE, not both".into(),
                    ));
                }
                if args.joints_deg.is_some() {
                    return Err(JobError::Options(
                        "--joints is for one target; a targets file gives its rows' joints \
                         as columns j1..jn"
                            .into(),
                    ));
                }
                let (columns, options) = args.reading.resolve()?;
                Asked::File(targets, columns, options)
            }
            None => {
                if args.output.is_some() {
                    return Err(JobError::Options(
                        "--output is for the answers to --targets FILE; one target's answer \
                         is printed"
                            .into(),
                    ));
                }
                Asked::One(one_target(&args.pose, args.config, tcp_mm)?)
            }
        };
        // SAFETY: tables are replaced by rename (`write_atomically`), never written in
        // place, so the mapped file does not change while the job holds it.
        let table = unsafe { Table::open(&args.table) }.map_err(|source| JobError::Table {
            path: args.table.clone(),
            source,
        })?;
        let work = match asked {
            Asked::One(mut one) => {
                if let Some(q) = &args.joints_deg {
                    one.joints_rad = Some(joints_rad(&table, q)?);
                }
                Work::One(one)
            }
            Asked::File(targets, columns, mut options) => {
                if let Some(output) = &args.output {
                    OutputPlan::check(&[output], &[&args.table, targets])?;
                }
                // The table's robot says which joints slide: their columns are lengths.
                options.prismatic_joints = table.prismatic_joints();
                Work::File {
                    rows: adwi_samples::read_targets(targets, &columns, &options)?,
                    output: args.output.clone(),
                }
            }
        };
        Ok(QueryJob {
            table,
            exact: args.exact,
            tcp_mm,
            work,
        })
    }

    /// The table the job answers from.
    pub fn table(&self) -> &Table<Mmap> {
        &self.table
    }

    /// Answers every target; writes the answers to a targets file's output (all or
    /// nothing) when one was given.
    ///
    /// # Errors
    ///
    /// [`JobError::Output`] when the output cannot be written.
    pub fn run(self) -> Result<QueryResult, JobError> {
        let table = &self.table;
        let orientation = table.has_orientation();
        let tier_name = if self.exact || !table.has_served_field() {
            "exact"
        } else {
            "served"
        };
        match self.work {
            Work::One(one) => {
                let joints = one.joints_rad.as_deref();
                let (c, command) = answer(
                    table,
                    &one.target,
                    joints,
                    self.exact,
                    Some(FixedPoint::default()),
                );
                let command_abc_deg = match (one.abc_deg, &command) {
                    (Some(abc), Some(command)) => {
                        let target_rotation = pose::rotation_from_kuka_abc_deg(abc);
                        let rotation =
                            pose::rotation_from_vector(command.rotation_rad) * target_rotation;
                        Some(pose::kuka_abc_deg_from_rotation(&rotation))
                    }
                    _ => None,
                };
                let joints_off = match (c.status, joints) {
                    (Status::JointsMismatch, Some(q)) => joints_off(table, &one.target, q),
                    _ => None,
                };
                let joint_beyond = match (c.status, joints) {
                    (Status::Ok, Some(q)) => joint_beyond(table, q),
                    _ => None,
                };
                let grid_mm = (c.status == Status::OutsideGrid).then(|| {
                    let g = table.grid();
                    let max = [0, 1, 2].map(|a| g.origin_mm[a] + g.cell_mm * f64::from(g.dims[a]));
                    [g.origin_mm, max]
                });
                Ok(QueryResult::One(Box::new(PointAnswer {
                    target_mm: one.target.position_mm,
                    grid_mm,
                    tier: tier_name,
                    answer: Answer::of(table, &c, orientation),
                    command,
                    command_abc_deg,
                    joints_off,
                    joint_beyond,
                })))
            }
            Work::File { rows, output } => {
                let answers = rows
                    .iter()
                    .map(|row| {
                        let target = Target {
                            tcp_mm: self.tcp_mm,
                            ..row.target
                        };
                        let (c, command) = answer(
                            table,
                            &target,
                            row.joints_rad.as_deref(),
                            self.exact,
                            Some(FixedPoint::default()),
                        );
                        RowAnswer {
                            target_mm: row.target.position_mm,
                            answer: Answer::of(table, &c, orientation),
                            command,
                        }
                    })
                    .collect();
                let answers = FileAnswers {
                    orientation,
                    rows: answers,
                    output,
                };
                if let Some(path) = &answers.output {
                    let mut csv = Vec::new();
                    answers
                        .write_csv(&mut csv)
                        .expect("writing to memory cannot fail");
                    write_atomically(path, &csv).map_err(JobError::from)?;
                }
                Ok(QueryResult::File(answers))
            }
        }
    }
}

/// One target's pose, checked: X Y Z or X Y Z A B C within any robot's range.
fn one_target(
    pose: &[f64],
    config: Option<u8>,
    tcp_mm: Option<[f64; 3]>,
) -> Result<OneTarget, JobError> {
    let (position_mm, abc_deg) = match pose {
        [x, y, z] => ([*x, *y, *z], None),
        [x, y, z, a, b, c] => ([*x, *y, *z], Some([*a, *b, *c])),
        _ => {
            return Err(JobError::Options(format!(
                "give a target as X Y Z or X Y Z A B C, or --targets FILE; {} numbers given",
                pose.len()
            )))
        }
    };
    check_pose(pose)?;
    // A non-finite orientation gives a non-finite rotation vector, which the table refuses
    // as it does a non-finite position (`invalid_input`): no command can be computed for it.
    Ok(OneTarget {
        target: Target {
            position_mm,
            config,
            rotation_rad: abc_deg
                .map(|abc| pose::rotation_vector(&pose::rotation_from_kuka_abc_deg(abc))),
            tcp_mm,
        },
        abc_deg,
        joints_rad: None,
    })
}

/// Refuses a target value that no robot takes, before the table answers: a position beyond
/// a kilometre, an angle beyond three turns. Such a value is a typing error, and an answer
/// to it (a command, `ok`) would be a number that means nothing. A value that is not finite
/// is the table's to refuse (status `invalid_input`).
fn check_pose(pose: &[f64]) -> Result<(), JobError> {
    let names = ["X", "Y", "Z", "A", "B", "C"];
    for (i, (name, v)) in names.iter().zip(pose).enumerate() {
        if !v.is_finite() {
            continue;
        }
        let checked = if i < 3 {
            args::check_coordinate_mm(name, *v)
        } else {
            args::check_angle_deg(name, *v)
        };
        checked.map_err(JobError::Options)?;
    }
    Ok(())
}

/// The `tcp` option: three coordinates within the plausible range.
fn tcp_of(tcp: Option<&[f64]>) -> Result<Option<[f64; 3]>, JobError> {
    let Some(tcp) = tcp else {
        return Ok(None);
    };
    let [x, y, z] = tcp else {
        return Err(JobError::Options(format!(
            "--tcp takes X,Y,Z (mm, flange frame); {} values given",
            tcp.len()
        )));
    };
    for (name, v) in ["--tcp X", "--tcp Y", "--tcp Z"].iter().zip([x, y, z]) {
        if !v.is_finite() {
            return Err(JobError::Options(format!("{name} is not a finite number")));
        }
        args::check_coordinate_mm(name, *v).map_err(JobError::Options)?;
    }
    Ok(Some([*x, *y, *z]))
}

/// The `joints` option in radians: as many values as the table's robot has joints, each
/// within three turns (revolute joints, degrees) or a kilometre (prismatic joints, mm).
/// Without a model the joints' kinds are unknown: each is held to the larger bound.
fn joints_rad<D: AsRef<[u8]>>(table: &Table<D>, joints_deg: &[f64]) -> Result<Vec<f64>, JobError> {
    let kinds = table.model().map(|m| m.nominal().joints());
    for (i, v) in joints_deg.iter().enumerate() {
        let name = format!("--joints J{}", i + 1);
        let kind = kinds.and_then(|k| k.get(i)).map(|j| j.kind);
        let checked = match kind {
            Some(JointKind::Revolute) => args::check_angle_deg(&name, *v),
            _ => args::check_coordinate_mm(&name, *v),
        };
        checked.map_err(JobError::Options)?;
    }
    if let Some(n) = table.joint_count() {
        if joints_deg.len() != n {
            return Err(JobError::Options(format!(
                "--joints takes the robot's {n} joint values, J1,...,J{n} (degrees; mm for a prismatic joint); {} given",
                joints_deg.len()
            )));
        }
    }
    Ok(joints_deg
        .iter()
        .enumerate()
        .map(
            |(i, v)| match kinds.and_then(|k| k.get(i)).map(|j| j.kind) {
                Some(JointKind::Prismatic) => *v,
                _ => v.to_radians(),
            },
        )
        .collect())
}

/// How far the joints' nominal forward kinematics puts the table's point from where the
/// target asks for it (as the query compared them, [`Table::joints_offset_mm`]), and the
/// distance the table allows, mm.
fn joints_off<D: AsRef<[u8]>>(
    table: &Table<D>,
    target: &Target,
    joints_rad: &[f64],
) -> Option<JointsOff> {
    Some(JointsOff {
        off_mm: table.joints_offset_mm(target, joints_rad)?,
        tolerance_mm: table.joints_tolerance_mm()?,
        tcp_placed: target.tcp_mm.is_some() && table.header().evidence.point_in_flange.is_some(),
    })
}

/// The joint farthest beyond the angles a version-6 hybrid table's samples span, when one
/// is: where the table's residual fades ([`adwi_runtime::joint_terms::RESIDUAL_FADE_RAD`]).
fn joint_beyond<D: AsRef<[u8]>>(table: &Table<D>, joints_rad: &[f64]) -> Option<JointBeyond> {
    let model = table.model().filter(|m| m.bounds_residual())?;
    let ranges = &model.joint_terms().range_rad;
    let (joint, beyond_rad) = (joints_rad.iter().zip(ranges).enumerate())
        .filter_map(|(j, (&q, &[lo, hi]))| {
            adwi_runtime::joint_terms::beyond_range(q, lo, hi).map(|(_, by)| (j, by))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let [lo, hi] = ranges[joint];
    Some(JointBeyond {
        joint: joint + 1,
        angle_deg: joints_rad[joint].to_degrees(),
        range_deg: [lo.to_degrees(), hi.to_degrees()],
        beyond_deg: beyond_rad.to_degrees(),
    })
}

/// What a query found.
#[derive(Debug, serde::Serialize)]
#[serde(untagged)]
pub enum QueryResult {
    /// The answer to one target.
    One(Box<PointAnswer>),
    /// The answers to every row of a targets file.
    File(FileAnswers),
}

/// A table's answer at a target, as a query reports it.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Answer {
    /// `ok`, or why the table gave no correction.
    pub status: &'static str,
    /// Whether `status` is `ok`.
    #[serde(skip)]
    pub ok: bool,
    /// Neighbours (exact tier) or nodes (served field) the answer drew on.
    pub neighbours: u32,
    /// The residual part of the answer: `full`, `faded` or `model_only` (a table without a
    /// model answers `full`); `None` without an answer.
    pub residual: Option<&'static str>,
    /// `within`, or what lies beyond the table's samples (`orientation`, `tcp`, ...).
    pub evidence: &'static str,
    /// Whether the answer lies within the table's samples.
    #[serde(skip)]
    pub within: bool,
    /// Whether a model answers what lies beyond the samples (a hybrid table).
    #[serde(skip)]
    pub hybrid: bool,
    /// The predicted position error, mm, base frame.
    pub error_mm: Option<[f64; 3]>,
    /// The predicted orientation error as a rotation vector, rad, base frame; `None` when
    /// the table carries none.
    pub orientation_error_rad: Option<[f64; 3]>,
}

impl Answer {
    fn of<D: AsRef<[u8]>>(table: &Table<D>, c: &Correction, orientation: bool) -> Answer {
        let ok = c.status == Status::Ok;
        Answer {
            status: c.status.as_str(),
            ok,
            neighbours: c.neighbours,
            residual: ok.then(|| c.residual.as_str()),
            evidence: if ok { c.evidence.as_str() } else { "" },
            within: !ok || c.evidence.is_within(),
            hybrid: table.is_hybrid(),
            error_mm: ok.then_some(c.position_error_mm),
            orientation_error_rad: (ok && orientation).then_some(c.orientation_error_rad),
        }
    }

    /// The evidence in words: `within`, or what lies beyond and who answers there.
    pub fn evidence_text(&self) -> String {
        if self.within {
            return "within".to_string();
        }
        let who = if self.hybrid {
            "the calibrated model answers"
        } else {
            "no model carries the answer"
        };
        format!("beyond: {} ({who})", self.evidence)
    }
}

/// How far `--joints` put the tool from the target.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct JointsOff {
    /// The distance of the joints' nominal TCP from the target, mm: of the table's point
    /// from the target moved back by the `--tcp` lever when `tcp_placed`, else of the
    /// table's point from the target itself.
    pub off_mm: f64,
    /// The distance the table allows, mm.
    pub tolerance_mm: f64,
    /// Whether the target named a TCP the table placed (it records its point in the
    /// flange): the distance is then the named TCP's from the target.
    pub tcp_placed: bool,
}

/// A joint commanded beyond the angles a hybrid table's samples span.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct JointBeyond {
    /// The joint, from 1.
    pub joint: usize,
    /// Its commanded angle, degrees.
    pub angle_deg: f64,
    /// The lowest and highest angles the samples span, degrees.
    pub range_deg: [f64; 2],
    /// How far beyond them the angle lies around the circle, degrees.
    pub beyond_deg: f64,
}

/// The answer to one target.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PointAnswer {
    /// The target's position, mm, base frame.
    pub target_mm: [f64; 3],
    /// The tier that answered: `served` or `exact`.
    pub tier: &'static str,
    /// The table's answer.
    #[serde(flatten)]
    pub answer: Answer,
    /// The command that lands on the target, when answered.
    pub command: Option<Command>,
    /// The command's orientation as KUKA A, B, C, degrees, when the target gave one.
    pub command_abc_deg: Option<[f64; 3]>,
    /// For a `joints_mismatch`: how far the joints put the tool.
    pub joints_off: Option<JointsOff>,
    /// For a hybrid table's answer: the joint farthest beyond the angles its samples span,
    /// if one is (its residual then fades: `faded` within 3°, `model_only` beyond).
    pub joint_beyond: Option<JointBeyond>,
    /// For an `outside_grid`: the grid's minimum and maximum corners, mm, base frame.
    pub grid_mm: Option<[[f64; 3]; 2]>,
}

impl PointAnswer {
    /// Whether the target was answered within the table's evidence.
    pub fn answered_within(&self) -> bool {
        self.answer.ok && self.answer.within
    }
}

/// The answer to one row of a targets file.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RowAnswer {
    /// The row's position, mm, base frame.
    pub target_mm: [f64; 3],
    /// The table's answer.
    #[serde(flatten)]
    pub answer: Answer,
    /// The command that lands on the row's target, when answered.
    pub command: Option<Command>,
}

/// The answers to every row of a targets file.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FileAnswers {
    /// Whether the answers carry orientation errors.
    pub orientation: bool,
    /// In the file's order.
    pub rows: Vec<RowAnswer>,
    /// The CSV written, if any.
    pub output: Option<PathBuf>,
}

impl FileAnswers {
    /// Rows answered beyond the table's evidence.
    pub fn beyond(&self) -> usize {
        self.rows
            .iter()
            .filter(|r| r.answer.ok && !r.answer.within)
            .count()
    }

    /// Rows not answered, by status, in the statuses' order of names.
    pub fn unanswered(&self) -> std::collections::BTreeMap<&'static str, usize> {
        let mut by_status = std::collections::BTreeMap::new();
        for r in self.rows.iter().filter(|r| !r.answer.ok) {
            *by_status.entry(r.answer.status).or_default() += 1;
        }
        by_status
    }

    /// The answers as CSV (docs/cli.md, `query --targets`): one line per row, empty fields
    /// where there is no value.
    ///
    /// # Errors
    ///
    /// Those of `out`.
    pub fn write_csv(&self, out: &mut impl Write) -> std::io::Result<()> {
        writeln!(
            out,
            "x,y,z,pred_dx,pred_dy,pred_dz,pred_rx,pred_ry,pred_rz,neighbours,status,residual,\
             command_x,command_y,command_z,command_rx,command_ry,command_rz,command_status,evidence"
        )?;
        for row in &self.rows {
            let p = row.target_mm;
            let a = &row.answer;
            write!(out, "{},{},{}", p[0], p[1], p[2])?;
            match a.error_mm {
                Some(e) => write!(out, ",{:.9},{:.9},{:.9}", e[0], e[1], e[2])?,
                None => write!(out, ",,,")?,
            }
            match a.orientation_error_rad {
                Some(r) => write!(out, ",{:.12},{:.12},{:.12}", r[0], r[1], r[2])?,
                None => write!(out, ",,,")?,
            }
            write!(out, ",{},{}", a.neighbours, a.status)?;
            match (a.ok, &row.command) {
                (true, Some(command)) => {
                    write!(out, ",{}", a.residual.unwrap_or(""))?;
                    let p = command.position_mm;
                    write!(out, ",{:.9},{:.9},{:.9}", p[0], p[1], p[2])?;
                    if self.orientation {
                        let r = command.rotation_rad;
                        write!(out, ",{:.12},{:.12},{:.12}", r[0], r[1], r[2])?;
                    } else {
                        write!(out, ",,,")?;
                    }
                    writeln!(out, ",{},{}", command.status.as_str(), a.evidence)?;
                }
                _ => writeln!(out, ",,,,,,,,,")?,
            }
        }
        Ok(())
    }
}
