//! `adwi._adwi`: the native half of the `adwi` Python package.
//!
//! Thin bindings that compose the workspace's crates as `tablec` does (its `build.rs`,
//! `query.rs` and `eval.rs`): the same reading options, the same table options and
//! defaults, the same refusal to overwrite an input, the same atomic write, the same
//! answers. The public Python API, with its docstrings, is `adwi/__init__.py`, which calls
//! the functions here.

use std::path::{Path, PathBuf};
use std::time::Instant;

use adwi_compile::build::{compile_plan, BuildOptions, BuildReport};
use adwi_compile::hybrid;
use adwi_samples::{
    AngleUnit, ColumnMap, Decimal, Delimiter, LengthUnit, ReadOptions, SampleSet,
};
use adwi_compile::write::{refuse_overwriting, write_atomically};
use adwi_eval::{EvalOptions, Method, Protocol};
use adwi_robot::calibrate::{CalibrateOptions, Calibration};
use adwi_robot::measured::Input;
use adwi_robot::register::{translation_and_rotation_deg, Refined, Registration};
use adwi_runtime::kinematics::Transform;
use adwi_runtime::method::MethodParams;
use adwi_runtime::{Correction, Status, Table as RuntimeTable, Target, Tier};
use anyhow::{bail, Context};
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

/// The paper's parameters, the defaults of every table option (as `tablec`'s).
const PAPER: MethodParams<()> = MethodParams::paper(());

/// The fixed-point compensation's tolerance, mm, and iteration bound, as `tablec query`'s.
const COMPENSATE_TOLERANCE_MM: f64 = 1e-6;
const COMPENSATE_ITERATIONS: u32 = 50;

/// Every status, indexed by its code (`Status as u8`).
const STATUSES: [Status; 7] = [
    Status::Ok,
    Status::OutsideGrid,
    Status::NoAdmissibleNeighbour,
    Status::InvalidInput,
    Status::MissingJoints,
    Status::NumericalFailure,
    Status::UncoveredCell,
];

// The codes are the statuses' own (`Status as u8`).
const _: () = {
    let mut i = 0;
    while i < STATUSES.len() {
        assert!(STATUSES[i] as usize == i);
        i += 1;
    }
};

/// The `command_status` names of `tablec query --targets`, indexed by code; code
/// [`NO_COMMAND`] is a row without a command (its status is not `ok`).
const COMMAND_STATUSES: [&str; 3] = ["converged", "not_converged", "first_order"];
const NO_COMMAND: u8 = 255;

/// An error as tablec prints it (its causes after colons), raised as [`AdwiError`].
fn adwi_error(e: anyhow::Error) -> PyErr {
    AdwiError::new_err(format!("{e:#}"))
}

/// Where samples come from: a file, or CSV text made from a DataFrame or an array (named
/// in messages by `name`).
#[derive(FromPyObject)]
enum Source {
    Data(String, Vec<u8>),
    Path(PathBuf),
}

impl Source {
    fn path(&self) -> Option<&Path> {
        match self {
            Source::Path(p) => Some(p),
            Source::Data(..) => None,
        }
    }

    /// The one reader's view of it, for base-frame samples and tracker-frame measurements
    /// alike.
    fn input(&self) -> Input<'_> {
        match self {
            Source::Path(p) => Input::File(p),
            Source::Data(name, bytes) => Input::Memory {
                name: Path::new(name),
                bytes,
            },
        }
    }

    fn describe(&self) -> String {
        match self {
            Source::Path(p) => p.display().to_string(),
            Source::Data(name, _) => name.clone(),
        }
    }
}

/// The reading options, as `tablec`'s `--columns`, `--delimiter`, `--decimal`,
/// `--length-unit` and `--angle-unit` take them.
#[derive(FromPyObject, Default)]
struct Reading {
    #[pyo3(item)]
    columns: Option<String>,
    #[pyo3(item)]
    delimiter: Option<String>,
    #[pyo3(item)]
    decimal: Option<String>,
    #[pyo3(item)]
    length_unit: Option<String>,
    #[pyo3(item)]
    angle_unit: Option<String>,
}

fn parse_option<T: std::str::FromStr<Err: std::fmt::Display>>(
    what: &str,
    text: &Option<String>,
) -> anyhow::Result<Option<T>> {
    text.as_deref()
        .map(|t| t.parse::<T>())
        .transpose()
        .map_err(|e| anyhow::anyhow!("{what}: {e}"))
}

impl Reading {
    fn resolve(&self) -> anyhow::Result<(ColumnMap, ReadOptions)> {
        let columns = ColumnMap::parse(self.columns.as_deref().unwrap_or(""))?;
        let options = ReadOptions {
            delimiter: parse_option::<Delimiter>("delimiter", &self.delimiter)?,
            decimal: parse_option::<Decimal>("decimal", &self.decimal)?,
            length_unit: parse_option::<LengthUnit>("length_unit", &self.length_unit)?
                .unwrap_or_default(),
            angle_unit: parse_option::<AngleUnit>("angle_unit", &self.angle_unit)?
                .unwrap_or_default(),
        };
        Ok((columns, options))
    }
}

/// The table options, as `tablec build` and `tablec eval` take them (`table_options.rs`).
#[derive(FromPyObject, Default)]
struct TableOptions {
    #[pyo3(item)]
    cell: Option<f64>,
    #[pyo3(item)]
    radius: Option<f64>,
    #[pyo3(item)]
    k: Option<u32>,
    #[pyo3(item)]
    w1: Option<f64>,
    #[pyo3(item)]
    w2: Option<f64>,
    #[pyo3(item)]
    power: Option<f64>,
    #[pyo3(item)]
    lambda_min: Option<f64>,
    #[pyo3(item)]
    zeta_min: Option<f64>,
    #[pyo3(item)]
    consistency_screen: Option<bool>,
    #[pyo3(item)]
    bounds: Option<[f64; 6]>,
    #[pyo3(item)]
    joint_radius: Option<f64>,
    #[pyo3(item)]
    served_field: Option<String>,
}

impl TableOptions {
    /// The compiler's options: the paper's parameters unless given, and one of ω1, ω2
    /// given implies the other (as `tablec`).
    fn build_options(&self) -> anyhow::Result<BuildOptions> {
        use adwi_compile::build::ServedField;
        let (w1, w2) = adwi_compile::build::resolve_weights(self.w1, self.w2);
        let served_field = match self.served_field.as_deref() {
            None => ServedField::Method,
            Some(name) => ServedField::from_name(name).ok_or_else(|| {
                anyhow::anyhow!(
                    "served_field '{name}': choose method, kriging or kriging-tool-axis"
                )
            })?,
        };
        Ok(BuildOptions {
            method: MethodParams {
                radius_mm: self.radius,
                max_neighbours: self.k.unwrap_or(PAPER.max_neighbours),
                w1,
                w2,
                power: self.power.unwrap_or(PAPER.power),
                lambda_min_per_mm: self.lambda_min.unwrap_or(PAPER.lambda_min_per_mm),
                zeta_min_per_mm2: self.zeta_min.unwrap_or(PAPER.zeta_min_per_mm2),
                consistency_screen: self.consistency_screen.unwrap_or(PAPER.consistency_screen),
            },
            cell_mm: self.cell,
            bounds_mm: self
                .bounds
                .map(|b| ([b[0], b[1], b[2]], [b[3], b[4], b[5]])),
            joint_radius_deg: self.joint_radius,
            tuning: None,
            served_field,
        })
    }
}

/// A robot file with the links of a URDF chain, as `tablec`'s `--robot`, `--base-link`
/// and `--tip-link`.
fn load_robot(
    path: &Path,
    base_link: Option<String>,
    tip_link: Option<String>,
) -> anyhow::Result<adwi_robot::Robot> {
    let links = adwi_robot::LinkNames {
        base_link,
        tip_link,
    };
    adwi_robot::Robot::load_with(path, &links)
        .with_context(|| format!("cannot load the robot {}", path.display()))
}

/// Whether `measured_in` (tablec's `--measured-in`) says the tracker's frame.
fn tracker_frame(measured_in: &str) -> anyhow::Result<bool> {
    match measured_in {
        "base" => Ok(false),
        "tracker" => Ok(true),
        other => bail!("measured_in '{other}': choose base or tracker"),
    }
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

/// What identification found, as `tablec build --hybrid` prints it.
fn calibration_dict<'py>(
    py: Python<'py>,
    c: &Calibration,
    residual_rms_mm: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let identified = PyDict::new(py);
    for p in &c.identified {
        identified.set_item(p.to_string(), c.value(*p))?;
    }
    d.set_item("identified", identified)?;
    let unidentifiable = PyDict::new(py);
    for (p, ratio) in &c.unidentifiable {
        unidentifiable.set_item(p.to_string(), *ratio)?;
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

/// A transform as `tablec` prints it (translation, mm; rotation vector, deg) and as its
/// rotation matrix (row-major), for those who apply it.
fn transform_dict<'py>(py: Python<'py>, t: &Transform) -> PyResult<Bound<'py, PyDict>> {
    let (translation_mm, rotation_deg) = translation_and_rotation_deg(t);
    let d = PyDict::new(py);
    d.set_item("translation_mm", translation_mm)?;
    d.set_item("rotation_vector_deg", rotation_deg)?;
    d.set_item("rotation", t.rotation)?;
    Ok(d)
}

/// Reads the samples as `measured_in` says (`tracker`: registered to `robot`), with the
/// robot every method then starts from: with tracker data, the one whose tool is the
/// registered probe.
fn read_measured(
    source: &Source,
    columns: &ColumnMap,
    read: &ReadOptions,
    robot: Option<adwi_robot::Robot>,
    tracker: bool,
) -> anyhow::Result<(
    Option<adwi_robot::measured::Registered>,
    SampleSet,
    Option<adwi_robot::Robot>,
)> {
    let (tracker_robot, robot) = if tracker {
        (robot, None)
    } else {
        (None, robot)
    };
    let (registered, samples) =
        adwi_robot::measured::read_samples(source.input(), columns, read, tracker_robot)?;
    let robot = registered.as_ref().map(|r| r.robot.clone()).or(robot);
    Ok((registered, samples, robot))
}

/// The registration of tracker-frame measurements, as `tablec` prints it: the rigid fit,
/// and both transforms as an identification of the registered samples refined them.
fn registration_dict<'py>(
    py: Python<'py>,
    r: &Registration,
    refined: Option<&Refined>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("rows", r.rows)?;
    d.set_item("orientation", r.orientation)?;
    d.set_item("iterations", r.iterations)?;
    transforms_into(py, &d, &r.fit())?;
    let refined = match refined {
        Some(f) => {
            let rd = PyDict::new(py);
            transforms_into(py, &rd, f)?;
            Some(rd)
        }
        None => None,
    };
    d.set_item("refined", refined)?;
    Ok(d)
}

/// Both transforms and the residuals they leave, under the same keys for the rigid fit and
/// for the refined transforms.
fn transforms_into(py: Python<'_>, d: &Bound<'_, PyDict>, t: &Refined) -> PyResult<()> {
    d.set_item("base_in_tracker", transform_dict(py, &t.base_in_tracker)?)?;
    d.set_item("probe", transform_dict(py, &t.probe)?)?;
    d.set_item("position_rms_mm", t.position_rms_mm)?;
    d.set_item("position_max_mm", t.position_max_mm)?;
    d.set_item("orientation_rms_rad", t.orientation_rms_rad)?;
    d.set_item("orientation_max_rad", t.orientation_max_rad)?;
    Ok(())
}

/// What a build made, for its report.
struct Built {
    samples: SampleSet,
    report: BuildReport,
    calibration: Option<(Calibration, f64)>,
    /// Tracker-frame samples' registration, refined by the hybrid's identification.
    registration: Option<(Registration, Refined)>,
    warnings: Vec<String>,
}

/// The build report: what `tablec build` prints, as numbers.
fn report_dict<'py>(
    py: Python<'py>,
    output: &Path,
    source: &Source,
    built: &Built,
    seconds: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let Built {
        samples,
        report,
        calibration,
        registration,
        warnings,
    } = built;
    let plan = &report.plan;
    let g = plan.grid;
    let m = plan.params;
    let d = PyDict::new(py);
    d.set_item("output", output.display().to_string())?;
    d.set_item("source", source.describe())?;
    d.set_item("samples", plan.samples)?;
    let repeats = match &samples.repeats {
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
    d.set_item("hybrid", calibration.is_some())?;
    d.set_item(
        "calibration",
        calibration
            .as_ref()
            .map(|(c, rms)| calibration_dict(py, c, *rms))
            .transpose()?,
    )?;
    d.set_item(
        "registration",
        registration
            .as_ref()
            .map(|(r, refined)| registration_dict(py, r, Some(refined)))
            .transpose()?,
    )?;
    d.set_item("warnings", warnings)?;
    d.set_item("seconds", seconds)?;
    Ok(d)
}

/// `tablec build`: read, plan, compile (hybrid with a robot), write atomically. Returns
/// the report as a dict.
#[pyfunction]
#[pyo3(signature = (source, output, reading, table, robot=None, base_link=None, tip_link=None, hybrid=false, threads=None, tune=false, tune_folds=5, compliance=false, measured_in="base"))]
#[allow(clippy::too_many_arguments)]
fn build<'py>(
    py: Python<'py>,
    source: Source,
    output: PathBuf,
    reading: Reading,
    table: TableOptions,
    robot: Option<PathBuf>,
    base_link: Option<String>,
    tip_link: Option<String>,
    hybrid: bool,
    threads: Option<usize>,
    tune: bool,
    tune_folds: usize,
    compliance: bool,
    measured_in: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let started = Instant::now();
    let built = py.allow_threads(|| -> anyhow::Result<_> {
        let mut inputs: Vec<&Path> = source.path().into_iter().collect();
        inputs.extend(robot.as_deref());
        refuse_overwriting(&output, &inputs)?;
        // As `tablec build --measured-in tracker`, which requires --hybrid and its --robot.
        let tracker = tracker_frame(measured_in)?;
        if tracker && robot.is_none() {
            bail!(
                "measured_in='tracker' needs the robot file the measurements are registered \
                 to: robot=PATH, with hybrid=True"
            );
        }
        if tracker && !hybrid {
            bail!("measured_in='tracker' is read for a hybrid table: give hybrid=True");
        }
        let robot = match (&robot, hybrid) {
            (Some(path), true) => Some(load_robot(path, base_link, tip_link)?),
            (Some(_), false) => {
                bail!("robot is only used by hybrid: give hybrid=True, or drop robot")
            }
            (None, true) => bail!("hybrid=True needs the robot file: robot=PATH"),
            (None, false) => None,
        };
        if compliance && !hybrid {
            bail!("compliance is identified by hybrid: give hybrid=True, or drop compliance");
        }
        // As `tablec build --hybrid [--compliance]`, for the tuning and the table alike.
        let calibrate_options = CalibrateOptions {
            compliance,
            ..CalibrateOptions::default()
        };
        let (columns, read) = reading.resolve()?;
        let (registered, samples, robot) = read_measured(&source, &columns, &read, robot, tracker)?;
        let mut options = table.build_options()?;
        if tune {
            if table.k.is_some() || table.radius.is_some() {
                bail!("tune chooses k and radius: give tune=True or k/radius, not both");
            }
            // As `tablec build --tune`: k and ε by cross-validation on these samples alone.
            let report = adwi_eval::tune::tune(
                &samples,
                robot.as_ref(),
                &options,
                &calibrate_options,
                tune_folds,
                0,
            )?;
            options = report.options;
        }
        let plan = adwi_compile::build::plan(&samples, &options)?;
        let mut warnings = Vec::new();
        if plan.is_mostly_empty() {
            warnings.push(format!(
                "the grid's {} cells are mostly empty: at most {:.0} of them lie within \
                 ε = {:.3} mm of a sample (samples along a line or a plane?); the table will \
                 be about {} — give bounds around the samples, or a larger cell",
                plan.cells(),
                plan.coverable_cells(),
                plan.params.radius_mm,
                adwi_compile::build::human_bytes(plan.estimated_table_bytes())
            ));
        }
        let mut pool = rayon::ThreadPoolBuilder::new();
        if let Some(n) = threads {
            pool = pool.num_threads(n);
        }
        let pool = pool.build().context("cannot start worker threads")?;
        let progress = |_| {};
        let mut calibration = None;
        let (bytes, report) = match &robot {
            Some(robot) => {
                let identified = pool.install(|| {
                    adwi_robot::calibrate::identify(robot, &samples, &calibrate_options)
                })?;
                let model = identified.prepared_model();
                let built = pool.install(|| hybrid::compile(&samples, &model, &plan, &progress))?;
                calibration = Some((identified, built.residual_position_rms_mm));
                (built.bytes, built.report)
            }
            None => {
                let hash = samples.source_hash();
                pool.install(|| compile_plan(&samples, &plan, None, hash, &progress))?
            }
        };
        write_atomically(&output, &bytes)
            .with_context(|| format!("cannot write {}", output.display()))?;
        if let Some((c, _)) = &calibration {
            if !c.unidentifiable.is_empty() {
                let dropped: Vec<String> = c
                    .unidentifiable
                    .iter()
                    .map(|(p, ratio)| format!("{p} ({ratio:.1e})"))
                    .collect();
                warnings.push(format!(
                    "unidentifiable from these samples (kept nominal; independent fraction \
                     in brackets): {}",
                    dropped.join(", ")
                ));
            }
        }
        let registration = registered.zip(calibration.as_ref()).map(|(r, (c, _))| {
            let refined = r.registration.refined(c, &samples);
            (r.registration, refined)
        });
        Ok(Built {
            samples,
            report,
            calibration,
            registration,
            warnings,
        })
    });
    let built = built.map_err(adwi_error)?;
    report_dict(
        py,
        &output,
        &source,
        &built,
        started.elapsed().as_secs_f64(),
    )
}

/// What [`evaluate`] returns: the records, the warnings, with tracker-frame samples
/// their registration and a validation set's own (registered apart), and the comparison
/// of the methods with the best.
type Evaluated<'py> = (
    Bound<'py, PyList>,
    Vec<String>,
    Option<Bound<'py, PyDict>>,
    Option<Bound<'py, PyDict>>,
    Option<Bound<'py, PyDict>>,
);

/// `tablec eval`: every method on held-out points. Returns (records, warnings,
/// registration, validation registration, comparison): one record per row of `tablec eval
/// --csv` (the uncompensated errors, then one per method), with the same keys, figures in
/// full precision; the registrations as `tablec eval` prints them, or None; the methods
/// against the best, point by point, as `"comparison"` in `tablec eval --json`.
#[pyfunction]
#[pyo3(signature = (source, reading, table, validation=None, limit=None, folds=None, seed=0, methods=None, robot=None, base_link=None, tip_link=None, rank_tol=None, keep_untrustworthy=false, compliance=false, measured_in="base", register_validation_apart=false))]
#[allow(clippy::too_many_arguments)]
fn evaluate<'py>(
    py: Python<'py>,
    source: Source,
    reading: Reading,
    table: TableOptions,
    validation: Option<Source>,
    limit: Option<usize>,
    folds: Option<usize>,
    seed: u64,
    methods: Option<Vec<String>>,
    robot: Option<PathBuf>,
    base_link: Option<String>,
    tip_link: Option<String>,
    rank_tol: Option<f64>,
    keep_untrustworthy: bool,
    compliance: bool,
    measured_in: &str,
    register_validation_apart: bool,
) -> PyResult<Evaluated<'py>> {
    let evaluated = py.allow_threads(|| -> anyhow::Result<_> {
        // As `tablec eval --measured-in tracker`, which requires --robot, and
        // --register-validation-apart, which requires --validation and a tracker frame.
        let tracker = tracker_frame(measured_in)?;
        if tracker && robot.is_none() {
            bail!(
                "measured_in='tracker' needs the robot file the measurements are registered \
                 to: robot=PATH"
            );
        }
        if register_validation_apart && validation.is_none() {
            bail!("register_validation_apart needs a validation set (validation=...)");
        }
        if register_validation_apart && !tracker {
            bail!("register_validation_apart needs measured_in='tracker'");
        }
        let (columns, read) = reading.resolve()?;
        let methods = methods
            .map(|names| {
                names
                    .iter()
                    .map(|n| n.parse::<Method>())
                    .collect::<Result<Vec<_>, _>>()
            })
            .transpose()
            .map_err(anyhow::Error::msg)?;
        let robot = robot
            .as_deref()
            .map(|p| load_robot(p, base_link, tip_link))
            .transpose()?;
        let (registered, samples, robot) = read_measured(&source, &columns, &read, robot, tracker)?;
        let calibrate = CalibrateOptions {
            rank_tolerance: rank_tol.unwrap_or(CalibrateOptions::default().rank_tolerance),
            hold_untrustworthy: !keep_untrustworthy,
            compliance,
            ..CalibrateOptions::default()
        };
        // The identification of all samples, as `tablec eval` makes it: the frame a
        // validation series is registered apart into, and what refines the registration.
        let mut registered_apart = None;
        let protocol = match (&validation, folds) {
            (Some(v), None) => {
                let (mut validation, apart) = adwi_robot::measured::read_validation(
                    v.input(),
                    &columns,
                    &read,
                    registered.as_ref(),
                    register_validation_apart.then_some((&samples, &calibrate)),
                )?;
                registered_apart = apart;
                if let Some(n) = limit {
                    if n == 0 {
                        bail!("limit must be at least 1");
                    }
                    let n = n.min(validation.len());
                    validation = adwi_eval::subset(&validation, &(0..n).collect::<Vec<_>>());
                }
                Protocol::Validation(validation)
            }
            (None, Some(folds)) => Protocol::KFold { folds, seed },
            (Some(_), Some(_)) => bail!("give a validation set or a fold count, not both"),
            (None, None) => {
                bail!("give a validation set (validation=...) or a fold count (folds=K)")
            }
        };
        let options = EvalOptions {
            methods,
            build: table.build_options()?,
            robot,
            calibrate,
            ..EvalOptions::default()
        };
        let evaluation = adwi_eval::evaluate(&samples, &protocol, &options)?;
        let identified = registered_apart.as_ref().map(|(_, c)| c);
        let registration = match registered {
            Some(r) => {
                let refined = r.refined_by(&samples, &options.calibrate, identified)?;
                Some((r.registration, refined))
            }
            None => None,
        };
        let validation_registration = registered_apart.map(|(r, _)| r);
        Ok((evaluation, registration, validation_registration))
    });
    let (e, registration, validation_registration) = evaluated.map_err(adwi_error)?;
    let mut warnings = Vec::new();
    for c in e.calibrations.iter().take(1) {
        if !c.unidentifiable.is_empty() {
            let names: Vec<&str> = c.unidentifiable.iter().map(|(n, _)| n.as_str()).collect();
            warnings.push(format!(
                "{} kinematic parameters cannot be identified from these samples and stay at \
                 nominal: {}",
                names.len(),
                names.join(", ")
            ));
        }
        if !c.converged {
            warnings.push(format!(
                "kinematic identification stopped after {} iterations without converging",
                c.iterations
            ));
        }
    }
    let records = PyList::empty(py);
    let record = |label: &str,
                  predicted: usize,
                  not_predicted: usize,
                  position: Option<&adwi_eval::baselines::ResidualStats>,
                  orientation: Option<&adwi_eval::baselines::ResidualStats>,
                  note: String|
     -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("method", label)?;
        d.set_item("predicted", predicted)?;
        d.set_item("not_predicted", not_predicted)?;
        for (prefix, unit, s) in [
            ("position", "mm", position),
            ("orientation", "mrad", orientation),
        ] {
            let figures = s.map(|s| [s.mean_norm, s.rms_norm, s.p95_norm, s.max_norm]);
            for (i, name) in ["mean", "rms", "p95", "max"].into_iter().enumerate() {
                d.set_item(format!("{prefix}_{name}_{unit}"), figures.map(|f| f[i]))?;
            }
        }
        let [se, p] = adwi_eval::output::resolution(position);
        d.set_item("position_mean_se_mm", se)?;
        d.set_item("position_offset_p", p)?;
        d.set_item("note", note)?;
        Ok(d)
    };
    records.append(record(
        "uncompensated",
        e.nominal_mm.len(),
        0,
        Some(&e.uncompensated_position_mm),
        e.uncompensated_orientation_mrad.as_ref(),
        String::new(),
    )?)?;
    for m in &e.methods {
        let note = match &m.unsupported {
            Some(reason) => format!("unsupported: {reason}"),
            None => m.not_predicted_summary().join("; "),
        };
        records.append(record(
            m.method.name(),
            m.predicted(),
            m.not_predicted_count(),
            m.position_mm.as_ref(),
            m.orientation_mrad.as_ref(),
            note,
        )?)?;
    }
    let registration = registration
        .map(|(r, refined)| registration_dict(py, &r, Some(&refined)))
        .transpose()?;
    let validation_registration = validation_registration
        .map(|r| registration_dict(py, &r, None))
        .transpose()?;
    let comparison = e
        .comparison
        .as_ref()
        .map(|c| -> PyResult<Bound<'py, PyDict>> {
            let d = PyDict::new(py);
            d.set_item("reference", c.reference.name())?;
            let against = PyList::empty(py);
            for a in &c.against {
                let row = PyDict::new(py);
                row.set_item("method", a.method.name())?;
                row.set_item("points", a.points)?;
                row.set_item("mean_difference_mm", a.mean_difference_mm)?;
                row.set_item("standard_error_mm", a.standard_error_mm)?;
                against.append(row)?;
            }
            d.set_item("against", against)?;
            Ok(d)
        })
        .transpose()?;
    Ok((
        records,
        warnings,
        registration,
        validation_registration,
        comparison,
    ))
}

/// A correction table, memory-mapped and validated once.
#[pyclass(frozen, module = "adwi._adwi")]
struct Table {
    table: RuntimeTable<memmap2::Mmap>,
    path: PathBuf,
}

/// The command for an answered target, as `tablec query` computes it: the fixed point of
/// `command + error(command) = target`; with joint angles, the first-order
/// `target − error`.
struct Command {
    position_mm: [f64; 3],
    rotation_rad: [f64; 3],
    status: u8,
    iterations: u32,
    residual_mm: f64,
}

fn command<D: AsRef<[u8]>>(
    table: &RuntimeTable<D>,
    target: &Target,
    joints_rad: Option<&[f64]>,
    c: &Correction,
    exact: bool,
    tolerance_mm: f64,
    max_iterations: u32,
) -> Command {
    if joints_rad.is_some() {
        let e = c.position_error_mm;
        return Command {
            position_mm: [0, 1, 2].map(|a| target.position_mm[a] - e[a]),
            rotation_rad: c.orientation_error_rad.map(|v| -v),
            status: 2,
            iterations: 0,
            residual_mm: f64::NAN,
        };
    }
    let comp = if exact {
        table
            .exact()
            .compensate(target, tolerance_mm, max_iterations)
    } else {
        table.compensate(target, tolerance_mm, max_iterations)
    };
    Command {
        position_mm: comp.command_position_mm,
        rotation_rad: comp.command_rotation_rad,
        status: if comp.converged { 0 } else { 1 },
        iterations: comp.iterations,
        residual_mm: comp.residual_mm,
    }
}

/// Per-row results of a batch, flat.
struct Batch {
    error: Vec<f64>,
    orientation: Vec<f64>,
    neighbours: Vec<u32>,
    status: Vec<u8>,
    command: Vec<f64>,
    command_rotation: Vec<f64>,
    command_status: Vec<u8>,
    iterations: Vec<u32>,
    residual: Vec<f64>,
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
    /// the commands when `compensate`. The GIL is released during the loop.
    #[pyo3(signature = (points, joints=None, config=None, exact=false, compensate=false, joints_deg=true, tolerance_mm=COMPENSATE_TOLERANCE_MM, max_iterations=COMPENSATE_ITERATIONS))]
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
    ) -> PyResult<Bound<'py, PyDict>> {
        let p = points.as_array();
        if p.ncols() != 3 {
            return Err(AdwiError::new_err(format!(
                "points must be an (N, 3) array of positions, mm; its shape is {:?}",
                p.shape()
            )));
        }
        let n = p.nrows();
        // Copied while the GIL is held: no other thread can change them during the loop.
        let positions: Vec<[f64; 3]> = p.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
        let joints: Option<(usize, Vec<f64>)> = match &joints {
            Some(j) => {
                let j = j.as_array();
                if j.nrows() != n {
                    return Err(AdwiError::new_err(format!(
                        "joints has {} rows, points {n}",
                        j.nrows()
                    )));
                }
                if let Some(count) = self.table.joint_count() {
                    if j.ncols() != count {
                        return Err(AdwiError::new_err(format!(
                            "joints must have the robot's {count} joint values per row, J1..J{count}; {} given",
                            j.ncols()
                        )));
                    }
                }
                // Degrees to radians by `f64::to_radians`, as `tablec query --joints`
                // (the reader's factor gives the same bits).
                let values = j
                    .iter()
                    .map(|&v| if joints_deg { v.to_radians() } else { v })
                    .collect();
                Some((j.ncols(), values))
            }
            None => None,
        };
        let config: Option<Vec<Option<u8>>> = match &config {
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
        let table = &self.table;
        let orientation = table.has_orientation();
        let batch = py.allow_threads(|| {
            let mut b = Batch {
                error: vec![f64::NAN; 3 * n],
                orientation: if orientation {
                    vec![f64::NAN; 3 * n]
                } else {
                    Vec::new()
                },
                neighbours: vec![0; n],
                status: vec![0; n],
                command: Vec::new(),
                command_rotation: Vec::new(),
                command_status: Vec::new(),
                iterations: Vec::new(),
                residual: Vec::new(),
            };
            if compensate {
                b.command = vec![f64::NAN; 3 * n];
                if orientation {
                    b.command_rotation = vec![f64::NAN; 3 * n];
                }
                b.command_status = vec![NO_COMMAND; n];
                b.iterations = vec![0; n];
                b.residual = vec![f64::NAN; n];
            }
            for (i, position) in positions.iter().enumerate() {
                let target = Target {
                    position_mm: *position,
                    config: config.as_ref().and_then(|c| c[i]),
                };
                let q = joints.as_ref().map(|(m, v)| &v[i * m..(i + 1) * m]);
                let c = table.answer(&target, q, if exact { Tier::Exact } else { Tier::Served });
                b.neighbours[i] = c.neighbours;
                b.status[i] = c.status as u8;
                if c.status != Status::Ok {
                    continue;
                }
                b.error[3 * i..3 * i + 3].copy_from_slice(&c.position_error_mm);
                if orientation {
                    b.orientation[3 * i..3 * i + 3].copy_from_slice(&c.orientation_error_rad);
                }
                if compensate {
                    let cmd = command(table, &target, q, &c, exact, tolerance_mm, max_iterations);
                    b.command[3 * i..3 * i + 3].copy_from_slice(&cmd.position_mm);
                    if orientation {
                        b.command_rotation[3 * i..3 * i + 3].copy_from_slice(&cmd.rotation_rad);
                    }
                    b.command_status[i] = cmd.status;
                    b.iterations[i] = cmd.iterations;
                    b.residual[i] = cmd.residual_mm;
                }
            }
            b
        });
        let d = PyDict::new(py);
        d.set_item("error_mm", matrix(py, batch.error, n)?)?;
        d.set_item(
            "orientation_rad",
            if orientation {
                Some(matrix(py, batch.orientation, n)?)
            } else {
                None
            },
        )?;
        d.set_item("neighbours", vector(py, batch.neighbours))?;
        d.set_item("status_code", vector(py, batch.status))?;
        if compensate {
            d.set_item("command_mm", matrix(py, batch.command, n)?)?;
            d.set_item(
                "command_rotation_rad",
                if orientation {
                    Some(matrix(py, batch.command_rotation, n)?)
                } else {
                    None
                },
            )?;
            d.set_item("command_status_code", vector(py, batch.command_status))?;
            d.set_item("iterations", vector(py, batch.iterations))?;
            d.set_item("residual_mm", vector(py, batch.residual))?;
        }
        Ok(d)
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

#[pymodule]
fn _adwi(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("AdwiError", m.py().get_type::<AdwiError>())?;
    m.add("STATUS_NAMES", STATUSES.map(|s| s.as_str()).to_vec())?;
    m.add("COMMAND_STATUS_NAMES", COMMAND_STATUSES.to_vec())?;
    m.add("NO_COMMAND", NO_COMMAND)?;
    m.add("COMPENSATE_TOLERANCE_MM", COMPENSATE_TOLERANCE_MM)?;
    m.add("COMPENSATE_ITERATIONS", COMPENSATE_ITERATIONS)?;
    m.add_class::<Table>()?;
    m.add_function(wrap_pyfunction!(build, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(array_csv, m)?)?;
    Ok(())
}
