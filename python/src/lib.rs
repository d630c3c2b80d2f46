//! `adwi._adwi`: the native half of the `adwi` Python package.
//!
//! The jobs are `adwi_jobs`' (the ones `tablec` runs): a job's keyword arguments
//! deserialize into its `*Args`, whose clap definition is also what documents them
//! ([`options`]), so that an option is defined once for both front ends. This module maps
//! arguments, runs the job with the GIL released, and converts the typed results into
//! dicts; the public Python API is `adwi/__init__.py`, its signatures `adwi/__init__.pyi`.

use std::path::PathBuf;

use adwi_jobs::{
    compensate, BuildArgs, BuildJob, CalibrateArgs, CalibrateJob, CalibrationSummary, EvalArgs,
    EvalJob, Iso9283Args, Iso9283Job, JobError, PlanArgs, PlanJob, RegistrationSummary, RobotArgs,
    Silent,
};
use adwi_runtime::{Residual, Status, Table as RuntimeTable, Target};
use anyhow::Context;
use clap::Args as _;
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

create_exception!(
    _adwi,
    AdwiError,
    PyValueError,
    "An input adwi refuses, as tablec refuses it: a bad sample row (the message carries \
     file:line:column), bad options, an unreadable or invalid table, an output that is one \
     of the inputs."
);

use adwi_jobs::query::{CommandStatus, FixedPoint, COMPENSATE_ITERATIONS, COMPENSATE_TOLERANCE_MM};

/// Every status, indexed by its code (`Status as u8`).
const STATUSES: [Status; 8] = [
    Status::Ok,
    Status::OutsideGrid,
    Status::NoAdmissibleNeighbour,
    Status::InvalidInput,
    Status::MissingJoints,
    Status::NumericalFailure,
    Status::UncoveredCell,
    Status::JointsMismatch,
];

// The codes are the statuses' own (`Status as u8`).
const _: () = {
    let mut i = 0;
    while i < STATUSES.len() {
        assert!(STATUSES[i] as usize == i);
        i += 1;
    }
};

/// The `residual` names of `tablec query`, indexed by code (`Residual as u8`); code
/// [`NO_RESIDUAL`] is a row without a correction (its status is not `ok`).
const RESIDUALS: [Residual; 3] = Residual::ALL;
const NO_RESIDUAL: u8 = 255;

// The codes are the flags' own (`Residual as u8`).
const _: () = {
    let mut i = 0;
    while i < RESIDUALS.len() {
        assert!(RESIDUALS[i] as usize == i);
        i += 1;
    }
};

/// The `command_status` names of `tablec query --targets`, indexed by code; code
/// [`NO_COMMAND`] is a row without a command (its status is not `ok`).
const COMMAND_STATUSES: [&str; 3] = [
    CommandStatus::ALL[0].as_str(),
    CommandStatus::ALL[1].as_str(),
    CommandStatus::ALL[2].as_str(),
];
const NO_COMMAND: u8 = 255;

/// An error as tablec prints it (its causes after colons), raised as [`AdwiError`], each
/// option named as Python's keyword arguments name it ([`adwi_jobs::keyword_spelling`]).
fn adwi_error(e: impl Into<anyhow::Error>) -> PyErr {
    AdwiError::new_err(adwi_jobs::keyword_spelling(&format!("{:#}", e.into())))
}

/// Where samples come from: a file, or CSV text made from a DataFrame or an array (named
/// in messages by its first item).
#[derive(FromPyObject)]
enum Source {
    Data(String, Vec<u8>),
    Path(PathBuf),
}

impl From<Source> for adwi_jobs::Source {
    fn from(s: Source) -> adwi_jobs::Source {
        match s {
            Source::Path(p) => adwi_jobs::Source::File(p),
            Source::Data(name, bytes) => adwi_jobs::Source::Memory {
                name: name.into(),
                bytes,
            },
        }
    }
}

/// The options of a job (`build`, `evaluate`, `calibrate`): each one's name, help text
/// and default as `tablec --help` gives them, the parameters of the Python function's own
/// signature (the sources, the output) left out. `__init__.py` documents the functions
/// from it.
fn job_options(job: &str) -> Option<clap::Command> {
    let command = clap::Command::new("adwi");
    Some(match job {
        "build" => BuildArgs::augment_args(command),
        "evaluate" => EvalArgs::augment_args(command),
        "calibrate" => CalibrateArgs::augment_args(command),
        "plan" => PlanArgs::augment_args(command),
        "iso9283" => Iso9283Args::augment_args(command),
        _ => return None,
    })
}

/// The parameters a job's Python function names in its signature, which are therefore not
/// among its keyword `**options`.
fn signature_parameters(job: &str) -> &'static [&'static str] {
    match job {
        "build" => &["samples", "output"],
        "evaluate" => &["samples", "validation"],
        "plan" => &["output"],
        "iso9283" => &["measurements"],
        _ => &["samples"],
    }
}

/// `[(name, help, default or None)]` of a job's options, for the docstrings.
#[pyfunction]
fn options(job: &str) -> PyResult<Vec<(String, String, Option<String>)>> {
    let command = job_options(job).ok_or_else(|| AdwiError::new_err(format!("no job '{job}'")))?;
    Ok(command
        .get_arguments()
        .filter(|a| !signature_parameters(job).contains(&a.get_id().as_str()) && !a.is_hide_set())
        .map(|a| {
            let help = a.get_help().map(|h| h.to_string()).unwrap_or_default();
            let default = a
                .get_default_values()
                .first()
                .map(|v| v.to_string_lossy().into_owned());
            (a.get_id().to_string(), help, default)
        })
        .collect())
}

/// A job's `*Args` from Python keyword arguments: names checked against the job's
/// options (an unknown one is refused with the known ones), values deserialized as the
/// command line's are parsed, a refusal naming the option.
fn job_args<T: serde::de::DeserializeOwned>(
    py: Python<'_>,
    job: &str,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<T> {
    let empty = PyDict::new(py);
    let kwargs = kwargs.unwrap_or(&empty);
    let command = job_options(job).expect("a known job");
    let known: Vec<String> = command
        .get_arguments()
        .map(|a| a.get_id().to_string())
        .filter(|id| !signature_parameters(job).contains(&id.as_str()))
        .collect();
    for key in kwargs.keys() {
        let key: String = key.extract()?;
        if !known.contains(&key) {
            return Err(AdwiError::new_err(format!(
                "{job}() has no option '{key}'; its options are {}",
                known.join(", ")
            )));
        }
    }
    // None stands for "not given": the option keeps its default.
    let given = PyDict::new(py);
    for (key, value) in kwargs.iter() {
        if !value.is_none() {
            given.set_item(key, value)?;
        }
    }
    let deserialize = |dict: &Bound<'_, PyDict>| -> Result<T, pythonize::PythonizeError> {
        T::deserialize(&mut pythonize::Depythonizer::from_object(dict.as_any()))
    };
    deserialize(&given).map_err(|e| {
        // Serde cannot say which key of a flattened struct failed: the option is found by
        // deserializing each one alone.
        let culprit = given.iter().find_map(|(key, value)| {
            let alone = PyDict::new(py);
            alone.set_item(&key, value).ok()?;
            let e = deserialize(&alone).err()?;
            Some((key.to_string(), e))
        });
        let (key, e) = culprit.map_or((None, e), |(k, e)| (Some(k), e));
        let message = e
            .to_string()
            .replace("expected u32", "expected a whole number from 0")
            .replace("expected usize", "expected a whole number from 0")
            .replace("expected u64", "expected a whole number from 0");
        match key {
            Some(key) => AdwiError::new_err(format!("{key}: {message}")),
            None => AdwiError::new_err(message),
        }
    })
}

/// The CSV text of an array whose columns are named by `header`: numbers written to the
/// last bit (Rust's shortest round-trip form), a non-finite value as `NaN` or `inf`, which
/// the reader refuses with its row and column, as it would in a file.
#[pyfunction]
fn array_csv(
    py: Python<'_>,
    array: PyReadonlyArray2<'_, f64>,
    header: Vec<String>,
) -> PyResult<Py<pyo3::types::PyBytes>> {
    use std::fmt::Write as _;
    let a = array.as_array();
    if a.ncols() != header.len() {
        return Err(AdwiError::new_err(format!(
            "the array has {} columns, its header {}",
            a.ncols(),
            header.len()
        )));
    }
    let mut out = header.join(",");
    out.push('\n');
    for row in a.rows() {
        for (i, v) in row.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            let _ = write!(out, "{v}");
        }
        out.push('\n');
    }
    Ok(pyo3::types::PyBytes::new(py, out.as_bytes()).unbind())
}

/// What identification found ([`CalibrationSummary`]), as `tablec build` (hybrid) prints
/// it: the identified values and the unidentifiable parameters by name, the figures, and
/// with `residual_rms_mm` what a hybrid table's residual tier starts from.
fn calibration_dict<'py>(
    py: Python<'py>,
    c: &CalibrationSummary,
    residual_rms_mm: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let identified = PyDict::new(py);
    for (p, value) in &c.identified {
        identified.set_item(p, *value)?;
    }
    d.set_item("identified", identified)?;
    let unidentifiable = PyDict::new(py);
    for (p, ratio) in &c.unidentifiable {
        unidentifiable.set_item(p, *ratio)?;
    }
    d.set_item("unidentifiable", unidentifiable)?;
    d.set_item("condition_number", c.condition_number)?;
    d.set_item("iterations", c.iterations)?;
    d.set_item("converged", c.converged)?;
    d.set_item("initial_position_rms_mm", c.initial_position_rms_mm)?;
    d.set_item("position_rms_mm", c.position_rms_mm)?;
    d.set_item("orientation_rms_rad", c.orientation_rms_rad)?;
    d.set_item("residual_position_rms_mm", residual_rms_mm)?;
    Ok(d)
}

/// A value as a dict (or list) by its `Serialize` form: what `--json` writes and the
/// Python package returns are one definition.
fn to_python<'py, T: serde::Serialize + ?Sized>(
    py: Python<'py>,
    value: &T,
) -> PyResult<Bound<'py, PyAny>> {
    pythonize::pythonize(py, value).map_err(|e| AdwiError::new_err(e.to_string()))
}

/// The registration of tracker-frame measurements, as `tablec` prints it
/// ([`RegistrationSummary`]): the rigid fit, and both transforms as an identification of
/// the registered samples refined them.
fn registration_dict<'py>(
    py: Python<'py>,
    r: Option<&RegistrationSummary>,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    r.map(|r| to_python(py, r)).transpose()
}

/// A job's warnings, as `tablec` prints them after `warning: `.
fn warning_texts(warnings: &[adwi_jobs::Warning]) -> Vec<String> {
    warnings.iter().map(|w| w.to_string()).collect()
}

/// Runs a job with the GIL released; its error raised as [`AdwiError`].
fn run_job<T: Send>(
    py: Python<'_>,
    job: impl FnOnce() -> Result<T, JobError> + Send,
) -> PyResult<T> {
    py.allow_threads(job).map_err(adwi_error)
}

/// `tablec build` ([`BuildJob`]). Returns the report as a dict.
#[pyfunction]
#[pyo3(signature = (sources, output, **options))]
fn build<'py>(
    py: Python<'py>,
    sources: Vec<Source>,
    output: PathBuf,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut args: BuildArgs = job_args(py, "build", options)?;
    args.samples = sources.into_iter().map(Into::into).collect();
    args.output = output;
    let built = run_job(py, || BuildJob::new(args)?.run(&Silent))?;
    let report = &built.report;
    let plan = &report.plan;
    let g = plan.grid;
    let m = plan.params;
    let d = PyDict::new(py);
    d.set_item("output", built.output.display().to_string())?;
    let sources: Vec<String> = built
        .sources
        .iter()
        .map(|s| s.display().to_string())
        .collect();
    d.set_item("source", sources.join(", "))?;
    d.set_item("sources", sources)?;
    d.set_item("samples", plan.samples)?;
    let repeats = match &built.repeats {
        Some(r) => {
            let rd = PyDict::new(py);
            rd.set_item("poses", r.poses)?;
            rd.set_item("rows", r.rows)?;
            rd.set_item("max_rows_per_pose", r.max_rows_per_pose)?;
            rd.set_item("position_max_mm", r.position_max_mm)?;
            rd.set_item("position_rms_mm", r.position_rms_mm)?;
            rd.set_item("orientation_max_mrad", r.orientation_max_mrad)?;
            rd.set_item("orientation_rms_mrad", r.orientation_rms_mrad)?;
            Some(rd)
        }
        None => None,
    };
    d.set_item("repeats", repeats)?;
    d.set_item("spacing_mm", plan.spacing_mm)?;
    d.set_item("radius_mm", m.radius_mm)?;
    d.set_item("radius_derived", plan.radius_derived)?;
    d.set_item("cell_mm", g.cell_mm)?;
    d.set_item("cell_derived", plan.cell_derived)?;
    d.set_item("grid_dims", g.dims)?;
    d.set_item("grid_origin_mm", g.origin_mm)?;
    d.set_item("grid_max_mm", g.max_mm())?;
    d.set_item("cells", plan.cells())?;
    d.set_item("covered_cells", report.cells_covered)?;
    d.set_item("distinct_lists", report.distinct_lists)?;
    d.set_item("list_entries", report.list_entries)?;
    d.set_item("mean_list_len", report.mean_list_len)?;
    d.set_item("max_list_len", report.max_list_len)?;
    d.set_item("served_cells", report.served_cells)?;
    d.set_item("node_sets", report.node_sets)?;
    d.set_item("bytes", report.table_bytes)?;
    d.set_item("k", m.max_neighbours)?;
    d.set_item("w1", m.w1)?;
    d.set_item("w2", m.w2)?;
    d.set_item("power", m.power)?;
    d.set_item("lambda_min", m.lambda_min_per_mm)?;
    d.set_item("zeta_min", m.zeta_min_per_mm2)?;
    d.set_item("consistency_screen", m.consistency_screen)?;
    d.set_item("joint_radius_deg", plan.joint_radius_rad.to_degrees())?;
    d.set_item("served_field", plan.served_field.name())?;
    // A kriging served field's hyperparameters per component (x, y, z, then orientation).
    let kriging = PyList::empty(py);
    for c in &report.served_kriging {
        let k = PyDict::new(py);
        k.set_item("length_scale_mm", c.length_scale)?;
        k.set_item("vertical_scale", c.vertical_scale)?;
        k.set_item("relative_nugget", c.relative_nugget)?;
        k.set_item("modulation", c.modulation)?;
        kriging.append(k)?;
    }
    d.set_item("served_kriging", kriging)?;
    let tuning = match plan.tuning {
        Some(t) => {
            let td = PyDict::new(py);
            td.set_item("folds", t.folds)?;
            td.set_item("cv_mean_mm", t.cv_mean_mm)?;
            td.set_item("served_cv_mean_mm", t.served_cv_mean_mm)?;
            Some(td)
        }
        None => None,
    };
    d.set_item("tuning", tuning)?;
    d.set_item("hybrid", built.calibration.is_some())?;
    d.set_item(
        "calibration",
        built
            .calibration
            .as_ref()
            .map(|(c, rms)| -> PyResult<_> {
                let summary = CalibrationSummary::of(c);
                let d = calibration_dict(py, &summary, Some(*rms))?;
                // Every parameter with its standard error and status, as `calibrate`'s.
                d.set_item("parameters", to_python(py, &summary.parameters)?)?;
                Ok(d)
            })
            .transpose()?,
    )?;
    let registration =
        (built.registration.as_ref()).map(|(r, refined)| RegistrationSummary::of(r, Some(refined)));
    d.set_item(
        "registration",
        registration_dict(py, registration.as_ref())?,
    )?;
    d.set_item("warnings", warning_texts(&built.warnings))?;
    d.set_item("seconds", built.seconds)?;
    Ok(d)
}

/// What [`evaluate`] returns: the records, the warnings, with tracker-frame samples
/// their registration and a validation set's own (registered apart), the comparison of
/// the methods with the best, and the records held out by region.
type Evaluated<'py> = (
    Bound<'py, PyAny>,
    Vec<String>,
    Option<Bound<'py, PyAny>>,
    Option<Bound<'py, PyAny>>,
    Option<Bound<'py, PyAny>>,
    Option<Bound<'py, PyAny>>,
);

/// `tablec eval` ([`EvalJob`]). Returns (records, warnings, registration, validation
/// registration, comparison, by-region records): one record per row of `tablec eval
/// --csv` (the uncompensated errors, then one per method), with the same keys, figures in
/// full precision; the registrations as `tablec eval` prints them, or None; the methods
/// against the best, point by point, as `"comparison"` in `tablec eval --json`; with
/// `by_region`, the records of the evaluation held out by region (or by series), as the
/// second table `tablec eval --by-region` prints, else None.
#[pyfunction]
#[pyo3(signature = (sources, validation=None, **options))]
fn evaluate<'py>(
    py: Python<'py>,
    sources: Vec<Source>,
    validation: Option<Source>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Evaluated<'py>> {
    let mut args: EvalArgs = job_args(py, "evaluate", options)?;
    args.samples = sources.into_iter().map(Into::into).collect();
    args.validation = validation.map(Into::into);
    let evaluated = run_job(py, || EvalJob::new(args)?.run("adwi.evaluate"))?;
    let (registration, validation_registration) = evaluated.registration_summaries();
    let comparison = (evaluated.evaluation.comparison.as_ref())
        .map(|c| to_python(py, c))
        .transpose()?;
    let by_region = (evaluated.by_region_records())
        .map(|r| to_python(py, &r))
        .transpose()?;
    Ok((
        to_python(py, &evaluated.records())?,
        warning_texts(&evaluated.warnings),
        registration_dict(py, registration.as_ref())?,
        registration_dict(py, validation_registration.as_ref())?,
        comparison,
        by_region,
    ))
}

/// `tablec calibrate` ([`CalibrateJob`]): the identification, the files written and the
/// warnings, as a dict.
#[pyfunction]
#[pyo3(signature = (sources, **options))]
fn calibrate<'py>(
    py: Python<'py>,
    sources: Vec<Source>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut args: CalibrateArgs = job_args(py, "calibrate", options)?;
    args.samples = sources.into_iter().map(Into::into).collect();
    let calibrated = run_job(py, || CalibrateJob::new(args)?.run())?;
    let d = calibration_dict(py, &calibrated.summary(), None)?;
    // What `--json` writes (the figures, the parameters, the truth), by the same code.
    let report = to_python(py, &calibrated.report())?.downcast_into::<PyDict>()?;
    d.update(report.as_mapping())?;
    let (registration, _) = calibrated.registration_summaries();
    d.set_item(
        "registration",
        registration_dict(py, registration.as_ref())?,
    )?;
    let written: Vec<String> = calibrated
        .written
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    d.set_item("written", written)?;
    d.set_item("warnings", warning_texts(&calibrated.warnings))?;
    Ok(d)
}

/// A correction table, memory-mapped and validated once.
#[pyclass(frozen, module = "adwi._adwi")]
struct Table {
    table: RuntimeTable<memmap2::Mmap>,
    path: PathBuf,
}

/// The rows of a batch, checked and copied while the GIL is held (no other thread can
/// change them while they are answered).
struct BatchRows {
    positions: Vec<[f64; 3]>,
    config: Option<Vec<Option<u8>>>,
    /// Values per row and the values, radians.
    joints: Option<(usize, Vec<f64>)>,
}

impl BatchRows {
    fn of<'py>(
        table: &RuntimeTable<memmap2::Mmap>,
        points: &PyReadonlyArray2<'py, f64>,
        joints: Option<&PyReadonlyArray2<'py, f64>>,
        config: Option<&PyReadonlyArray1<'py, i64>>,
        joints_deg: bool,
    ) -> PyResult<BatchRows> {
        let p = points.as_array();
        if p.ncols() != 3 {
            return Err(AdwiError::new_err(format!(
                "points must be an (N, 3) array of positions, mm; its shape is {:?}",
                p.shape()
            )));
        }
        let n = p.nrows();
        let positions = p.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
        let joints = match joints {
            Some(j) => {
                let j = j.as_array();
                if j.nrows() != n {
                    return Err(AdwiError::new_err(format!(
                        "joints has {} rows, points {n}",
                        j.nrows()
                    )));
                }
                if let Some(count) = table.joint_count() {
                    if j.ncols() != count {
                        return Err(AdwiError::new_err(format!(
                            "joints must have the robot's {count} joint values per row, J1..J{count}; {} given",
                            j.ncols()
                        )));
                    }
                }
                // Degrees to radians by `f64::to_radians`, as `tablec query --joints`
                // (the reader's factor gives the same bits); a prismatic joint's value is
                // mm either way.
                let prismatic = table.prismatic_joints();
                let columns = j.ncols();
                let values = j
                    .iter()
                    .enumerate()
                    .map(|(k, &v)| {
                        let joint = (k % columns) as u32;
                        let angle = prismatic.checked_shr(joint).unwrap_or(0) & 1 == 0;
                        if joints_deg && angle {
                            v.to_radians()
                        } else {
                            v
                        }
                    })
                    .collect();
                Some((j.ncols(), values))
            }
            None => None,
        };
        let config = match config {
            Some(c) => {
                let c = c.as_array();
                if c.len() != n {
                    return Err(AdwiError::new_err(format!(
                        "config has {} values, points {n} rows",
                        c.len()
                    )));
                }
                let mut out = Vec::with_capacity(n);
                for &v in c.iter() {
                    out.push(match v {
                        v if v < 0 => None,
                        v if v <= 254 => Some(v as u8),
                        v => {
                            return Err(AdwiError::new_err(format!(
                                "configuration {v} out of range: 0 to 254, or negative for unknown"
                            )))
                        }
                    });
                }
                Some(out)
            }
            None => None,
        };
        Ok(BatchRows {
            positions,
            config,
            joints,
        })
    }
}

/// Per-row results of a batch, flat.
struct Batch {
    /// Whether the answers carry orientation errors.
    with_orientation: bool,
    /// Whether the commands were asked for.
    with_commands: bool,
    error: Vec<f64>,
    orientation: Vec<f64>,
    neighbours: Vec<u32>,
    status: Vec<u8>,
    residual_flag: Vec<u8>,
    evidence: Vec<u8>,
    command: Vec<f64>,
    command_rotation: Vec<f64>,
    command_status: Vec<u8>,
    iterations: Vec<u32>,
    residual: Vec<f64>,
}

impl Batch {
    /// Every row answered as `tablec query --targets` answers it ([`adwi_jobs::query::answer`]).
    fn answer(
        table: &RuntimeTable<memmap2::Mmap>,
        rows: &BatchRows,
        exact: bool,
        fixed_point: Option<FixedPoint>,
        tcp: Option<[f64; 3]>,
    ) -> Batch {
        let n = rows.positions.len();
        let orientation = table.has_orientation();
        let compensate = fixed_point.is_some();
        let rows_of = |on: bool, len: usize| if on { vec![f64::NAN; len] } else { Vec::new() };
        let mut b = Batch {
            with_orientation: orientation,
            with_commands: compensate,
            error: vec![f64::NAN; 3 * n],
            orientation: rows_of(orientation, 3 * n),
            neighbours: vec![0; n],
            status: vec![0; n],
            residual_flag: vec![NO_RESIDUAL; n],
            evidence: vec![0; n],
            command: rows_of(compensate, 3 * n),
            command_rotation: rows_of(compensate && orientation, 3 * n),
            command_status: if compensate {
                vec![NO_COMMAND; n]
            } else {
                Vec::new()
            },
            iterations: if compensate { vec![0; n] } else { Vec::new() },
            residual: rows_of(compensate, n),
        };
        for (i, position) in rows.positions.iter().enumerate() {
            let target = Target {
                position_mm: *position,
                config: rows.config.as_ref().and_then(|c| c[i]),
                rotation_rad: None,
                tcp_mm: tcp,
            };
            let q = rows.joints.as_ref().map(|(m, v)| &v[i * m..(i + 1) * m]);
            let (c, cmd) = adwi_jobs::query::answer(table, &target, q, exact, fixed_point);
            b.neighbours[i] = c.neighbours;
            b.status[i] = c.status as u8;
            if c.status != Status::Ok {
                continue;
            }
            b.residual_flag[i] = c.residual as u8;
            b.evidence[i] = c.evidence.0;
            b.error[3 * i..3 * i + 3].copy_from_slice(&c.position_error_mm);
            if orientation {
                b.orientation[3 * i..3 * i + 3].copy_from_slice(&c.orientation_error_rad);
            }
            if let Some(cmd) = cmd {
                b.command[3 * i..3 * i + 3].copy_from_slice(&cmd.position_mm);
                if orientation {
                    b.command_rotation[3 * i..3 * i + 3].copy_from_slice(&cmd.rotation_rad);
                }
                b.command_status[i] = cmd.status.code();
                b.iterations[i] = cmd.iterations;
                b.residual[i] = cmd.fixed_point_residual_mm.unwrap_or(f64::NAN);
            }
        }
        b
    }

    /// The arrays as the Python side reads them (`adwi.Answer`).
    fn into_dict(self, py: Python<'_>, n: usize) -> PyResult<Bound<'_, PyDict>> {
        let d = PyDict::new(py);
        let orientation = self.with_orientation;
        d.set_item("error_mm", matrix(py, self.error, n)?)?;
        d.set_item(
            "orientation_rad",
            if orientation {
                Some(matrix(py, self.orientation, n)?)
            } else {
                None
            },
        )?;
        d.set_item("neighbours", vector(py, self.neighbours))?;
        d.set_item("status_code", vector(py, self.status))?;
        d.set_item("residual_code", vector(py, self.residual_flag))?;
        d.set_item("evidence_code", vector(py, self.evidence))?;
        if self.with_commands {
            d.set_item("command_mm", matrix(py, self.command, n)?)?;
            d.set_item(
                "command_rotation_rad",
                if orientation {
                    Some(matrix(py, self.command_rotation, n)?)
                } else {
                    None
                },
            )?;
            d.set_item("command_status_code", vector(py, self.command_status))?;
            d.set_item("iterations", vector(py, self.iterations))?;
            d.set_item("residual_mm", vector(py, self.residual))?;
        }
        Ok(d)
    }
}

fn matrix<'py>(py: Python<'py>, values: Vec<f64>, n: usize) -> PyResult<PyObject> {
    let a =
        Array2::from_shape_vec((n, 3), values).map_err(|e| AdwiError::new_err(e.to_string()))?;
    Ok(a.into_pyarray(py).into_any().unbind())
}

fn vector<'py, T: numpy::Element>(py: Python<'py>, values: Vec<T>) -> PyObject {
    Array1::from_vec(values)
        .into_pyarray(py)
        .into_any()
        .unbind()
}

#[pymethods]
impl Table {
    /// Opens a table by memory map and validates it.
    #[staticmethod]
    fn open(py: Python<'_>, path: PathBuf) -> PyResult<Table> {
        let table = py
            .allow_threads(|| {
                // SAFETY: tables are replaced by rename (write_atomically), never written in
                // place, so the mapped file does not change while this object holds it.
                unsafe { RuntimeTable::open(&path) }
                    .with_context(|| format!("cannot open table {}", path.display()))
            })
            .map_err(adwi_error)?;
        Ok(Table { table, path })
    }

    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    #[getter]
    fn has_orientation(&self) -> bool {
        self.table.has_orientation()
    }

    #[getter]
    fn has_config(&self) -> bool {
        self.table.has_config()
    }

    #[getter]
    fn is_hybrid(&self) -> bool {
        self.table.is_hybrid()
    }

    #[getter]
    fn joint_count(&self) -> Option<usize> {
        self.table.joint_count()
    }

    #[getter]
    fn joint_radius_deg(&self) -> f64 {
        self.table.joint_radius_rad().to_degrees()
    }

    #[getter]
    fn has_served_field(&self) -> bool {
        self.table.has_served_field()
    }

    #[getter]
    fn sample_count(&self) -> usize {
        self.table.sample_count()
    }

    #[getter]
    fn version(&self) -> u16 {
        self.table.header().version
    }

    #[getter]
    fn source_hash(&self) -> u64 {
        self.table.header().source_hash
    }

    #[getter]
    fn grid<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let g = self.table.grid();
        let d = PyDict::new(py);
        d.set_item("origin_mm", g.origin_mm)?;
        d.set_item("max_mm", g.max_mm())?;
        d.set_item("cell_mm", g.cell_mm)?;
        d.set_item("dims", g.dims)?;
        d.set_item("cells", g.cell_count())?;
        Ok(d)
    }

    #[getter]
    fn method<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let m = self.table.method();
        let d = PyDict::new(py);
        d.set_item("radius_mm", m.radius_mm)?;
        d.set_item("k", m.max_neighbours)?;
        d.set_item("w1", m.w1)?;
        d.set_item("w2", m.w2)?;
        d.set_item("power", m.power)?;
        d.set_item("lambda_min", m.lambda_min_per_mm)?;
        d.set_item("zeta_min", m.zeta_min_per_mm2)?;
        d.set_item("consistency_screen", m.consistency_screen)?;
        Ok(d)
    }

    /// Answers every row of `points` ((N, 3) mm) as `tablec query --targets` does, with
    /// `joints` ((N, n); degrees when `joints_deg`, as `tablec` reads `j1..jn`, else rad)
    /// and `config` ((N,), negative for unknown) when given, and with
    /// the commands when `compensate`. `tcp` (X, Y, Z mm, flange frame) names the TCP the
    /// points are for, as `tablec query --tcp`; `evidence_code` says where each answer lies
    /// beyond the table's samples (0 within, bit 0 orientation, bit 1 TCP). The GIL is
    /// released during the loop.
    #[pyo3(signature = (points, joints=None, config=None, exact=false, compensate=false, joints_deg=true, tolerance_mm=COMPENSATE_TOLERANCE_MM, max_iterations=COMPENSATE_ITERATIONS, tcp=None))]
    #[allow(clippy::too_many_arguments)]
    fn query_batch<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
        joints: Option<PyReadonlyArray2<'py, f64>>,
        config: Option<PyReadonlyArray1<'py, i64>>,
        exact: bool,
        compensate: bool,
        joints_deg: bool,
        tolerance_mm: f64,
        max_iterations: u32,
        tcp: Option<[f64; 3]>,
    ) -> PyResult<Bound<'py, PyDict>> {
        if let Some(t) = tcp {
            if !t.iter().all(|v| v.is_finite() && v.abs() <= 1e6) {
                return Err(AdwiError::new_err(format!(
                    "tcp must be three finite coordinates within a kilometre, mm; {t:?} given"
                )));
            }
        }
        let fixed_point = if compensate {
            Some(FixedPoint::new(tolerance_mm, max_iterations).map_err(adwi_error)?)
        } else {
            None
        };
        let rows = BatchRows::of(
            &self.table,
            &points,
            joints.as_ref(),
            config.as_ref(),
            joints_deg,
        )?;
        let table = &self.table;
        let batch = py.allow_threads(|| Batch::answer(table, &rows, exact, fixed_point, tcp));
        batch.into_dict(py, rows.positions.len())
    }

    fn __repr__(&self) -> String {
        let g = self.table.grid();
        format!(
            "Table('{}': {} samples, {} × {} × {} cells of {} mm{}{})",
            self.path.display(),
            self.table.sample_count(),
            g.dims[0],
            g.dims[1],
            g.dims[2],
            g.cell_mm,
            if self.table.has_orientation() {
                ", orientation"
            } else {
                ""
            },
            if self.table.is_hybrid() {
                ", hybrid"
            } else {
                ""
            }
        )
    }
}

// ---------------------------------------------------------------------------------------
// Robot programs compensated offline: `tablec compensate` (adwi_jobs::CompensateJob).

/// `tablec compensate`: the job checks every option and input before any work, corrects
/// every target, and writes `output` (and `report`, as CSV) atomically when given.
/// Returns (the compensated program's bytes, one dict per target, the summary dict).
#[pyfunction]
#[pyo3(signature = (table, program, output=None, report=None, format=None, robot=None, base_link=None, tip_link=None, flange_link=None, tool=None, base=None, table_tool=None, max_correction_mm=compensate::DEFAULT_MAX_CORRECTION_MM, max_joint_change_deg=compensate::DEFAULT_MAX_JOINT_CHANGE_DEG, strict=false, max_seconds=compensate::DEFAULT_MAX_SECONDS, beyond_evidence=false, krl_config=None, fanuc_uframes=None, fanuc_utools=None, fanuc_frames=None, fanuc_turn_axes=None, fanuc_j23=None, yaskawa_tools=None, yaskawa_users=None, yaskawa_pulses_per_deg=None))]
#[allow(clippy::too_many_arguments)]
fn compensate_program<'py>(
    py: Python<'py>,
    table: PathBuf,
    program: PathBuf,
    output: Option<PathBuf>,
    report: Option<PathBuf>,
    format: Option<String>,
    robot: Option<PathBuf>,
    base_link: Option<String>,
    tip_link: Option<String>,
    flange_link: Option<String>,
    tool: Option<[f64; 6]>,
    base: Option<[f64; 6]>,
    table_tool: Option<[f64; 6]>,
    max_correction_mm: f64,
    max_joint_change_deg: f64,
    strict: bool,
    max_seconds: f64,
    beyond_evidence: bool,
    krl_config: Option<PathBuf>,
    fanuc_uframes: Option<std::collections::BTreeMap<u16, [f64; 6]>>,
    fanuc_utools: Option<std::collections::BTreeMap<u16, [f64; 6]>>,
    fanuc_frames: Option<PathBuf>,
    fanuc_turn_axes: Option<Vec<i64>>,
    fanuc_j23: Option<f64>,
    yaskawa_tools: Option<std::collections::BTreeMap<u16, [f64; 6]>>,
    yaskawa_users: Option<std::collections::BTreeMap<u16, [f64; 6]>>,
    yaskawa_pulses_per_deg: Option<Vec<f64>>,
) -> PyResult<(
    Bound<'py, pyo3::types::PyBytes>,
    Bound<'py, PyList>,
    Bound<'py, PyDict>,
)> {
    use compensate::{CompensateArgs, CompensateJob};
    let mut args = CompensateArgs::new(table, program);
    args.output = output;
    args.report = report;
    args.format = format;
    args.robot = RobotArgs {
        robot,
        base_link,
        tip_link,
        flange_link,
    };
    args.tool = tool;
    args.base = base;
    args.table_tool = table_tool;
    args.max_correction_mm = max_correction_mm;
    args.max_joint_change_deg = max_joint_change_deg;
    args.strict = strict;
    args.max_seconds = max_seconds;
    args.beyond_evidence = beyond_evidence;
    args.krl_config = krl_config;
    // Fanuc user and tool frames by number, X, Y, Z, W, P, R (mm, degrees).
    args.fanuc_uframe = fanuc_uframes.unwrap_or_default().into_iter().collect();
    args.fanuc_utool = fanuc_utools.unwrap_or_default().into_iter().collect();
    args.fanuc_frames = fanuc_frames;
    // The joints of a CONFIG's turn numbers, as the command line's J,J,J.
    args.fanuc_turn_axes = fanuc_turn_axes
        .map(|axes| {
            let text = axes
                .iter()
                .map(i64::to_string)
                .collect::<Vec<_>>()
                .join(",");
            adwi_jobs::compensate::parse_turn_axes(&text)
                .map_err(|e| AdwiError::new_err(format!("fanuc_turn_axes: {e}")))
        })
        .transpose()?;
    args.fanuc_j23 = fanuc_j23;
    // Yaskawa tool files and user frames by number, X, Y, Z, Rx, Ry, Rz (mm, degrees), and
    // the axes' pulses per degree.
    args.yaskawa_tool = yaskawa_tools.unwrap_or_default().into_iter().collect();
    args.yaskawa_user = yaskawa_users.unwrap_or_default().into_iter().collect();
    args.yaskawa_pulses_per_deg = yaskawa_pulses_per_deg;
    let done = py
        .allow_threads(|| -> Result<_, adwi_jobs::JobError> {
            let job = CompensateJob::new(args)?;
            let done = job.run()?;
            job.write(&done)?;
            Ok(done)
        })
        .map_err(|e| AdwiError::new_err(e.to_string()))?;
    let targets = PyList::empty(py);
    for t in &done.targets {
        let d = PyDict::new(py);
        d.set_item("name", &t.name)?;
        d.set_item("line", t.line)?;
        d.set_item("column", t.column)?;
        d.set_item("in_partner", t.in_partner)?;
        d.set_item("kind", t.kind)?;
        d.set_item("status", t.status.as_str())?;
        d.set_item("detail", &t.detail)?;
        d.set_item("correction_mm", t.correction_mm)?;
        d.set_item("rotation_deg", t.rotation_deg)?;
        d.set_item("joint_change_deg", t.joint_change_deg)?;
        d.set_item("iterations", t.iterations)?;
        d.set_item("residual_mm", t.residual_mm)?;
        d.set_item("residual", t.residual.map(Residual::as_str))?;
        d.set_item("evidence", t.evidence.map(adwi_runtime::Evidence::as_str))?;
        d.set_item("point_mm", t.point_mm)?;
        d.set_item("command_mm", t.command_mm)?;
        d.set_item("command_joints", t.command_joints.clone())?;
        targets.append(d)?;
    }
    let s = &done.summary;
    let summary = PyDict::new(py);
    summary.set_item("total", s.total)?;
    summary.set_item("corrected", s.corrected)?;
    let not_corrected = PyDict::new(py);
    for (status, count) in &s.not_corrected {
        not_corrected.set_item(status, count)?;
    }
    summary.set_item("not_corrected", not_corrected)?;
    summary.set_item("residual_faded", s.faded)?;
    summary.set_item("residual_model_only", s.model_only)?;
    summary.set_item("beyond_evidence", s.beyond_evidence)?;
    summary.set_item("largest_correction_mm", s.largest.as_ref().map(|l| l.0))?;
    summary.set_item("largest_at", s.largest.as_ref().map(|l| l.1.clone()))?;
    summary.set_item("text", s.to_string())?;
    Ok((
        pyo3::types::PyBytes::new(py, &done.output),
        targets,
        summary,
    ))
}

#[pymodule]
fn _adwi(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("AdwiError", m.py().get_type::<AdwiError>())?;
    m.add("STATUS_NAMES", STATUSES.map(|s| s.as_str()).to_vec())?;
    m.add("COMMAND_STATUS_NAMES", COMMAND_STATUSES.to_vec())?;
    m.add("NO_COMMAND", NO_COMMAND)?;
    m.add("RESIDUAL_NAMES", RESIDUALS.map(|r| r.as_str()).to_vec())?;
    m.add("NO_RESIDUAL", NO_RESIDUAL)?;
    m.add("COMPENSATE_TOLERANCE_MM", COMPENSATE_TOLERANCE_MM)?;
    m.add("COMPENSATE_ITERATIONS", COMPENSATE_ITERATIONS)?;
    m.add_class::<Table>()?;
    m.add_function(wrap_pyfunction!(build, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(plan, m)?)?;
    m.add_function(wrap_pyfunction!(iso9283, m)?)?;
    m.add_function(wrap_pyfunction!(options, m)?)?;
    m.add_function(wrap_pyfunction!(array_csv, m)?)?;
    m.add_function(wrap_pyfunction!(compensate_program, m)?)?;
    Ok(())
}

/// `tablec plan` ([`PlanJob`]): the poses planned, in the order to measure them, and the
/// criterion, as a dict.
#[pyfunction]
#[pyo3(signature = (output, **options))]
fn plan<'py>(
    py: Python<'py>,
    output: PathBuf,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut args: PlanArgs = job_args(py, "plan", options)?;
    args.output = output;
    let planned = run_job(py, || PlanJob::new(args)?.run(&Silent))?;
    let p = &planned.plan;
    let d = PyDict::new(py);
    d.set_item("robot", &planned.robot_name)?;
    let joints: Vec<Vec<f64>> = p.poses.iter().map(|q| q.joints.clone()).collect();
    d.set_item("joints_rad", joints)?;
    let positions: Vec<[f64; 3]> = p.poses.iter().map(|q| q.position_mm).collect();
    d.set_item("position_mm", positions)?;
    let abc: Vec<[f64; 3]> = p.poses.iter().map(|q| q.abc_deg).collect();
    d.set_item("abc_deg", abc)?;
    let parameters: Vec<String> = p.parameters.iter().map(|q| q.to_string()).collect();
    d.set_item("parameters", parameters)?;
    d.set_item("pool", p.pool)?;
    d.set_item("draws", p.draws)?;
    d.set_item("log_det", p.log_det)?;
    d.set_item("mean_variance", p.mean_variance)?;
    d.set_item("variance_bound", p.variance_bound)?;
    d.set_item("criterion_value", p.criterion_value)?;
    d.set_item("criterion_bound", p.criterion_bound)?;
    d.set_item("planned", pythonize::pythonize(py, &p.planned)?)?;
    let random = p
        .random
        .iter()
        .map(|f| pythonize::pythonize(py, f))
        .collect::<Result<Vec<_>, _>>()?;
    d.set_item("random", random)?;
    d.set_item("field_variance_mm2", p.field_variance_mm2)?;
    // With the tracker's MPE the variances are in mm², not per σ².
    d.set_item("tracker_sigma_mm", p.tracker_sigma_mm)?;
    d.set_item("workspace_candidates", p.workspace_candidates)?;
    d.set_item("other_branches", p.other_branches)?;
    d.set_item("min_distance_mm", p.min_distance_mm)?;
    d.set_item("path_travel", p.path_travel)?;
    d.set_item("written", vec![planned.output.display().to_string()])?;
    Ok(d)
}

/// `tablec iso9283` ([`Iso9283Job`]): the characteristics of measured cycles (and, with
/// a table, of their compensation), or the cube plan written, as a dict.
#[pyfunction]
#[pyo3(signature = (measurements=None, **options))]
fn iso9283<'py>(
    py: Python<'py>,
    measurements: Option<PathBuf>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut args: Iso9283Args = job_args(py, "iso9283", options)?;
    args.measurements = measurements;
    let result = run_job(py, || Iso9283Job::new(args)?.run())?;
    let d = PyDict::new(py);
    match result
        .report
        .as_ref()
        .map(|r| to_python(py, r))
        .transpose()?
    {
        Some(report) => {
            let report = report.downcast_into::<PyDict>()?;
            d.set_item("positions", report.get_item("positions")?)?;
            d.set_item("distance", report.get_item("distance")?)?;
            d.set_item(
                "orientation_convention",
                report.get_item("orientation_convention")?,
            )?;
            d.set_item("notes", report.get_item("notes")?)?;
        }
        None => {
            d.set_item("positions", PyList::empty(py))?;
            d.set_item("distance", PyList::empty(py))?;
            d.set_item("orientation_convention", py.None())?;
            d.set_item("notes", PyList::empty(py))?;
        }
    }
    let convert = |report: Option<&_>| report.map(|r| to_python(py, r)).transpose();
    d.set_item("compensated", convert(result.compensated.as_ref())?)?;
    // The path characteristics of a tracker stream (path=..., command=...).
    let convert_path = |report: Option<&_>| report.map(|r| to_python(py, r)).transpose();
    d.set_item("path", convert_path(result.path.as_ref())?)?;
    d.set_item(
        "path_compensated",
        convert_path(result.path_compensated.as_ref())?,
    )?;
    let written: Vec<String> = result
        .written
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    d.set_item("written", written)?;
    Ok(d)
}
