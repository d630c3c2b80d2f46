//! Compiling a sample database into a cell table.
//!
//! The workspace box is cut into cubic cells. For every cell the table stores a candidate
//! list: every sample that can be among the `k` nearest admissible samples of *some*
//! target inside the cell. The runtime then only examines that list, and its answer equals
//! the brute-force reference's for every target in the grid. A sample is listed when
//!
//! - it can be within ε of a point of the cell (its distance to the cell box is at most ε),
//!   and
//! - it is not *dominated*: fewer than `k` other samples are certainly admissible
//!   everywhere in the cell (farthest distance to the box within ε) and certainly nearer
//!   (their farthest distance below its nearest distance). With configurations, the count
//!   is also taken among samples of its own configuration, since a target of that
//!   configuration sees only those. With λ or ζ thresholds, or with the joint-space screen
//!   ([`BuildOptions::joint_radius_deg`]), admissibility depends on more than the distance,
//!   no sample is certain, and nothing is pruned beyond the radius.
//!
//! Boxes are grown by [`BOX_MARGIN_MM`] and comparisons carry [`DISTANCE_SLACK_MM`], far
//! above floating-point rounding, so that a target on a cell face, or rounded into a
//! neighbouring cell, still finds every sample it needs. Each list goes into its cell's own
//! 64-byte record (the exact tier reads one cache line), or, when longer than a record
//! holds, into an overflow array.
//!
//! The served tier is then the method evaluated at every node of the grid, through the
//! list of a cell the node is a corner of — the base weights at each node, applied — once
//! for targets of unknown configuration and once per configuration the samples carry
//! ([`adwi_runtime::served`]). With [`BuildOptions::served_field`] set to
//! [`ServedField::Kriging`] (or [`ServedField::KrigingToolAxis`]), the nodes hold instead
//! kriging with a nugget of the samples' errors ([`crate::nugget_kriging`], fitted once per
//! set of samples a configuration sees): a smoother field that does not pass each sample's
//! measurement noise on. The method's nodes are missing wherever it has no admissible
//! sample, so its served field stops up to one cell short of the exact tier. The kriging is
//! defined everywhere, and its nodes are filled at every corner of a cell whose candidate
//! list holds a sample the set may use: every cell in which the exact tier can answer is
//! then served, and the served field misses no target the exact tier answers.
//!
//! Cells and nodes are processed in parallel; results are assembled in order, so the
//! bytes written do not depend on the number of threads.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};

use adwi_runtime::format::{
    self, v2, Grid, Header, SampleRecord, CONTENT_CONFIG, CONTENT_JOINTS, CONTENT_MODEL,
    CONTENT_ORIENTATION,
};
pub use adwi_runtime::format::{ServedField, Tuning};
use adwi_runtime::method::{self, MethodParams, CONFIG_UNKNOWN};
use adwi_runtime::model::PreparedModel;
use rayon::prelude::*;

use adwi_samples::SampleSet;

/// Cell boxes are grown by this much (mm) when computing candidate lists.
pub const BOX_MARGIN_MM: f64 = 1e-6;
/// Slack (mm) in every distance comparison that decides a candidate list.
pub const DISTANCE_SLACK_MM: f64 = 1e-9;
/// The most cells a table may have.
pub const MAX_CELLS: usize = 20_000_000;
/// The default radius ε is this many sample spacings: it covers the 8 corners of a lattice
/// cube (at most √3 spacings away) from any point inside it.
pub const RADIUS_PER_SPACING: f64 = 2.0;
/// The default cell edge is the sample spacing divided by this: cells half a spacing wide
/// keep a cell's candidates within one 64-byte record for lattice-like samples, and put
/// the served field's nodes twice as dense as the samples.
pub const CELLS_PER_SPACING: f64 = 2.0;

/// What `tablec build` is asked for; `None` fields are derived from the samples.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildOptions {
    /// The method's parameters; ε (`radius_mm`) defaults to [`RADIUS_PER_SPACING`] × the
    /// sample spacing.
    pub method: MethodParams<Option<f64>>,
    /// Cell edge, mm; default the sample spacing / [`CELLS_PER_SPACING`].
    pub cell_mm: Option<f64>,
    /// The grid's box (min, max corners, mm); default the samples' nominal bounding box
    /// grown by ε.
    pub bounds_mm: Option<([f64; 3], [f64; 3])>,
    /// The joint-space admissibility radius, degrees: when the target's joint angles are
    /// known, a sample is admissible only if every joint angle is within this of the
    /// target's (`Header::joint_radius_rad`). `None` (or 0) turns the screen off. Needs
    /// samples with joint angles.
    pub joint_radius_deg: Option<f64>,
    /// The cross-validation that chose these options, recorded in the table's header
    /// (`tablec build --tune`); `None` when they were given or defaulted.
    pub tuning: Option<Tuning>,
    /// What the served tier's nodes hold (module docs).
    pub served_field: ServedField,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            method: MethodParams::paper(None),
            cell_mm: None,
            bounds_mm: None,
            joint_radius_deg: None,
            tuning: None,
            served_field: ServedField::Method,
        }
    }
}

/// The weights ω1 and ω2 from what a user gave: the paper's when neither is given, and
/// `1 − ω` for the one not given, so that they sum to 1 unless both are given.
pub fn resolve_weights(w1: Option<f64>, w2: Option<f64>) -> (f64, f64) {
    let paper = MethodParams::paper(());
    match (w1, w2) {
        (None, None) => (paper.w1, paper.w2),
        (Some(w1), None) => (w1, 1.0 - w1),
        (None, Some(w2)) => (1.0 - w2, w2),
        (Some(w1), Some(w2)) => (w1, w2),
    }
}

/// Why a table could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// A parameter is out of range.
    #[error("invalid parameter: {0}")]
    Params(&'static str),
    /// ε or the cell size were not given and cannot be derived.
    #[error("cannot derive {0} from a single sample: give it explicitly")]
    CannotDerive(&'static str),
    /// The bounds are not a box.
    #[error("invalid bounds: {0}")]
    Bounds(String),
    /// The grid would be too large.
    #[error(
        "the grid would have {cells} cells of {cell_mm:.3} mm (a table of about {}), more than \
         the {max} allowed: choose a larger --cell or a smaller --bounds",
        human_bytes(*estimated_bytes)
    )]
    TooManyCells {
        /// Cells requested.
        cells: u128,
        /// The cell edge, mm.
        cell_mm: f64,
        /// The table's estimated size, bytes.
        estimated_bytes: u128,
        /// The limit.
        max: usize,
    },
    /// A hybrid table needs the samples' joint angles, at which its model is evaluated.
    #[error("a hybrid table needs samples with joint angles (columns j1..jn)")]
    MissingJoints,
    /// A parameter, the grid or the samples are outside the range the runtime accepts.
    #[error("implausible table: {0}")]
    Implausible(format::Implausible),
    /// The samples' joint values do not fit the model's joint count.
    #[error("the samples have {samples} joint values each, the robot model {model} joints")]
    JointCount {
        /// The model's joint count.
        model: usize,
        /// The samples' joint values per sample.
        samples: usize,
    },
    /// Serialisation failed.
    #[error("cannot encode the table: {0}")]
    Encode(String),
    /// The kriging of a served field could not be fitted.
    #[error("cannot fit the kriging of the served field")]
    Kriging(#[source] crate::nugget_kriging::GpError),
    /// A served field that turns with the tool was asked of a table without a model.
    #[error("the kriging-tool-axis served field needs a hybrid table (a robot model and samples with joint angles): the tool's axis comes from its nominal chain")]
    ToolAxisWithoutModel,
    /// A kriging served field was asked of a table that has none (a joint screen).
    #[error("a kriging served field needs a served tier, which a table with a joint screen does not have")]
    KrigingWithoutServedTier,
    /// The encoded table does not open: a bug of the compiler, never a property of the
    /// input.
    #[error("the built table does not open: please report this bug")]
    Unopenable(#[source] adwi_runtime::OpenError),
}

impl From<format::Implausible> for BuildError {
    fn from(e: format::Implausible) -> BuildError {
        BuildError::Implausible(e)
    }
}

/// A build resolved from its options and samples, once: every parameter the table will
/// hold, and what was derived. [`compile_plan`] consumes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// The method's parameters, ε resolved.
    pub params: MethodParams,
    /// The cell grid.
    pub grid: Grid,
    /// The joint-space admissibility radius, rad (0 = off).
    pub joint_radius_rad: f64,
    /// Median nearest-neighbour spacing of the nominal positions, mm.
    pub spacing_mm: Option<f64>,
    /// Whether ε was derived from the spacing.
    pub radius_derived: bool,
    /// Whether the cell edge was derived from the spacing.
    pub cell_derived: bool,
    /// The number of samples planned for.
    pub samples: usize,
    /// The cross-validation that chose the options, for the header.
    pub tuning: Option<Tuning>,
    /// What the served tier's nodes hold.
    pub served_field: ServedField,
}

impl Plan {
    /// The number of cells in the grid.
    pub fn cells(&self) -> usize {
        self.grid.cell_count().unwrap_or(0)
    }

    /// At most how many cells can hold candidates ([`max_covered_cells`]).
    pub fn coverable_cells(&self) -> f64 {
        max_covered_cells(self.samples, self.params.radius_mm, self.grid.cell_mm)
            .min(self.cells() as f64)
    }

    /// Whether most of a large grid lies farther than ε from every sample, as it does for
    /// samples along a line or a plane, whose bounding box is mostly empty.
    pub fn is_mostly_empty(&self) -> bool {
        self.cells() > 100_000 && self.cells() as f64 > 10.0 * self.coverable_cells()
    }

    /// The table's estimated size, bytes ([`estimated_table_bytes`]).
    pub fn estimated_table_bytes(&self) -> u128 {
        estimated_table_bytes(
            self.cells() as u128,
            self.samples,
            self.params.radius_mm,
            self.grid.cell_mm,
            self.params.max_neighbours,
        )
    }
}

/// What a build produced, for the CLI to report.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildReport {
    /// The plan it followed.
    pub plan: Plan,
    /// Cells whose candidate list is not empty.
    pub cells_covered: usize,
    /// Distinct candidate lists stored.
    pub distinct_lists: usize,
    /// Total entries over the distinct lists.
    pub list_entries: usize,
    /// The longest candidate list.
    pub max_list_len: usize,
    /// Mean candidate list length over covered cells.
    pub mean_list_len: f64,
    /// Table size, bytes.
    pub table_bytes: usize,
    /// Cells the served field covers (all 8 nodes answered, for targets of unknown
    /// configuration); 0 without a served tier.
    pub served_cells: usize,
    /// Node sets of the served tier (0: the exact tier alone answers).
    pub node_sets: usize,
    /// A kriging served field's hyperparameters, chosen by likelihood, per component
    /// (x, y, z, then the orientation's), of the fit serving targets of any configuration;
    /// empty when the nodes hold the method's answer.
    pub served_kriging: Vec<crate::nugget_kriging::GpChoice>,
}

/// A table's size before it is built, bytes: per cell its 8-byte record and base-weight
/// offset, per cell that can be covered ([`max_covered_cells`]) at most `k` base weights
/// (12 bytes each), and per sample its record.
pub fn estimated_table_bytes(
    cells: u128,
    samples: usize,
    radius_mm: f64,
    cell_mm: f64,
    k: u32,
) -> u128 {
    let covered = (max_covered_cells(samples, radius_mm, cell_mm) as u128).min(cells);
    // Saturating: an absurd grid (a huge --radius, say) must be refused, not overflow.
    cells
        .saturating_mul(12)
        .saturating_add(covered.saturating_mul(12 * u128::from(k)))
        .saturating_add(samples as u128 * 120)
}

/// At most how many cells of edge `cell_mm` can lie within `radius_mm` of one of `samples`
/// points: the cells a ball of that radius, grown by half a cell diagonal, can touch, per
/// sample. A grid far larger than this is mostly empty (samples on a line or a plane).
pub fn max_covered_cells(samples: usize, radius_mm: f64, cell_mm: f64) -> f64 {
    let reach_cells = radius_mm / cell_mm + 3f64.sqrt();
    samples as f64 * 4.0 / 3.0 * std::f64::consts::PI * reach_cells.powi(3)
}

/// `1234567` as `1.2 MB`.
pub fn human_bytes(bytes: u128) -> String {
    let units = ["bytes", "kB", "MB", "GB", "TB", "PB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1000.0 && unit + 1 < units.len() {
        value /= 1000.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} bytes")
    } else {
        format!("{value:.1} {}", units[unit])
    }
}

/// Resolves a build's options against its samples: derives ε, the cell edge and the grid
/// where not given, and checks everything the runtime will check, before any work.
///
/// # Errors
///
/// Parameters out of range, underivable defaults, a grid too large or implausible.
pub fn plan(samples: &SampleSet, options: &BuildOptions) -> Result<Plan, BuildError> {
    let spacing_mm = samples.spacing_mm();
    let derive = |what| {
        spacing_mm
            .filter(|s| *s > 0.0)
            .ok_or(BuildError::CannotDerive(what))
    };
    let radius_mm = match options.method.radius_mm {
        Some(r) => r,
        None => RADIUS_PER_SPACING * derive("the radius")?,
    };
    let params = options.method.with_radius(radius_mm);
    params.validate().map_err(BuildError::Params)?;
    let joint_radius_rad = options.joint_radius_deg.unwrap_or(0.0).to_radians();
    if !(joint_radius_rad.is_finite() && joint_radius_rad >= 0.0) {
        return Err(BuildError::Params(
            "joint radius must be finite and non-negative",
        ));
    }
    if joint_radius_rad > 0.0 && options.served_field != ServedField::Method {
        return Err(BuildError::KrigingWithoutServedTier);
    }
    if joint_radius_rad > 0.0 && samples.joints.is_none() {
        return Err(BuildError::Params(
            "a joint radius needs samples with joint angles (columns j1..jn)",
        ));
    }
    let cell_mm = match options.cell_mm {
        Some(c) => c,
        None => derive("the cell size")? / CELLS_PER_SPACING,
    };
    if !(cell_mm.is_finite() && cell_mm > 0.0) {
        return Err(BuildError::Params("cell size must be finite and positive"));
    }
    let (lo, hi) = match options.bounds_mm {
        Some(b) => b,
        None => {
            let (lo, hi) = samples
                .nominal_bounds_mm()
                .ok_or(BuildError::CannotDerive("bounds"))?;
            (lo.map(|v| v - radius_mm), hi.map(|v| v + radius_mm))
        }
    };
    if !(0..3).all(|a| lo[a].is_finite() && hi[a].is_finite() && lo[a] < hi[a]) {
        return Err(BuildError::Bounds(format!(
            "{lo:?} to {hi:?}: each minimum must be below its maximum, all finite"
        )));
    }
    // Bounds a kilometre away (a huge --radius widens the default ones) are refused before
    // their cells are counted.
    for v in lo.iter().chain(&hi) {
        format::check_coordinate("a grid bound (mm)", *v)?;
    }
    let dims_f = [0, 1, 2].map(|a| ((hi[a] - lo[a]) / cell_mm).ceil().max(1.0));
    // Saturating: a tiny cell makes each count reach u128::MAX (`as` saturates).
    let cells = dims_f
        .iter()
        .fold(1u128, |product, &d| product.saturating_mul(d as u128));
    if cells > MAX_CELLS as u128 || dims_f.iter().any(|&d| d > u32::MAX as f64) {
        return Err(BuildError::TooManyCells {
            cells,
            cell_mm,
            estimated_bytes: estimated_table_bytes(
                cells,
                samples.len(),
                radius_mm,
                cell_mm,
                params.max_neighbours,
            ),
            max: MAX_CELLS,
        });
    }
    let grid = Grid {
        origin_mm: lo,
        cell_mm,
        dims: dims_f.map(|d| d as u32),
    };
    // The runtime's own plausibility bounds, so that no build ends in a table that does
    // not open (an ε beyond every distance in the workspace, a grid a kilometre away).
    let positions = (0..samples.len()).flat_map(|i| [samples.nominal_mm[i], samples.actual_mm(i)]);
    format::check_plausible(
        &params,
        &grid,
        joint_radius_rad,
        format::bounding_box(positions),
    )?;
    Ok(Plan {
        params,
        grid,
        joint_radius_rad,
        spacing_mm,
        radius_derived: options.method.radius_mm.is_none(),
        cell_derived: options.cell_mm.is_none(),
        samples: samples.len(),
        tuning: options.tuning,
        served_field: options.served_field,
    })
}

/// Plans and compiles `samples` into table bytes: [`plan`], then [`compile_plan`].
/// `progress(n)` is called as cells complete, with the number just completed (from
/// several threads).
///
/// # Errors
///
/// Parameters out of range, underivable defaults, a grid too large.
pub fn compile(
    samples: &SampleSet,
    options: &BuildOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<u8>, BuildReport), BuildError> {
    let plan = plan(samples, options)?;
    compile_plan(samples, &plan, None, samples.source_hash(), progress)
}

/// Compiles `samples` into table bytes as `plan` (from [`plan`] over the same samples, or
/// the measured ones of a hybrid table) says. With a kinematic `model`, `samples` hold the
/// residuals the model leaves and `source_hash` identifies the measured samples they were
/// derived from ([`crate::hybrid`] builds hybrid tables through this).
///
/// # Errors
///
/// An implausible model, an encoding failure.
pub fn compile_plan(
    samples: &SampleSet,
    plan: &Plan,
    model: Option<&PreparedModel>,
    source_hash: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<u8>, BuildReport), BuildError> {
    let Plan { params, grid, .. } = *plan;
    let mut report = BuildReport {
        plan: *plan,
        cells_covered: 0,
        distinct_lists: 0,
        list_entries: 0,
        max_list_len: 0,
        mean_list_len: 0.0,
        table_bytes: 0,
        served_cells: 0,
        node_sets: 0,
        served_kriging: Vec::new(),
    };
    if let Some(model) = model {
        for chain in [model.nominal(), model.calibrated()] {
            format::check_chain_plausible(chain)?;
        }
    }
    let joint_count = match (&samples.joints, model) {
        (Some(j), Some(m)) if j.count() != m.joint_count() => {
            return Err(BuildError::JointCount {
                model: m.joint_count(),
                samples: j.count(),
            })
        }
        (Some(j), _) => j.count(),
        (None, Some(m)) => m.joint_count(),
        (None, None) => 0,
    };
    let joint_screen = plan.joint_radius_rad > 0.0;
    let records = samples.records();
    let index = SpatialIndex::new(&records, params.radius_mm);
    let done = AtomicU64::new(0);
    let lists: Vec<Vec<u32>> = (0..plan.cells())
        .into_par_iter()
        .map(|cell| {
            let candidates = candidate_list(&records, &index, &params, joint_screen, &grid, cell);
            if done.fetch_add(1, Ordering::Relaxed) % 4096 == 4095 {
                progress(4096);
            }
            candidates
        })
        .collect();
    progress(done.load(Ordering::Relaxed) % 4096);

    let mut data = v2::TableData {
        samples: records
            .iter()
            .map(|r| v2::QuerySample {
                actual_mm: r.actual_mm,
                norm_mm: method::norm_mm(r.actual_mm),
            })
            .collect(),
        errors_mm: samples.error_mm.clone(),
        orientation_errors_rad: samples.rotation_error_rad.clone().unwrap_or_default(),
        configs: samples.config.clone().unwrap_or_default(),
        joints_rad: match (&samples.joints, joint_screen) {
            (Some(j), true) => j.as_flat().to_vec(),
            _ => Vec::new(),
        },
        model: model.map(|m| v2::ModelRecord {
            nominal: v2::ChainRecord::from_chain(m.nominal()),
            calibrated: v2::ChainRecord::from_chain(m.calibrated()),
        }),
        ..v2::TableData::default()
    };
    let narrow = records.len() <= v2::NARROW_SAMPLES;
    let mut distinct = std::collections::HashSet::new();
    for list in &lists {
        if narrow {
            data.cells.push(narrow_record(list, &mut data.overflow));
        } else {
            data.cells_wide.push(wide_record(list, &mut data.overflow));
        }
        if !list.is_empty() {
            report.cells_covered += 1;
            report.max_list_len = report.max_list_len.max(list.len());
            report.mean_list_len += list.len() as f64;
            report.list_entries += list.len();
            distinct.insert(list.as_slice());
        }
    }
    report.mean_list_len /= report.cells_covered.max(1) as f64;
    report.distinct_lists = distinct.len();

    // The served tier: the exact method at every node, one set per target configuration
    // (none with a joint screen: its admissible samples depend on the joint values).
    if !joint_screen {
        let field = match plan.served_field {
            ServedField::Method => NodeField::Method,
            ServedField::Kriging => NodeField::Kriging(None),
            ServedField::KrigingToolAxis => NodeField::Kriging(Some(tool_axes(samples, model)?)),
        };
        let served = NodeValues::compute(&records, &params, &grid, &lists, samples, &field)?;
        report.node_sets = served.sets.len();
        report.served_cells = served.served_cells(&grid);
        report.served_kriging = served.kriging_choices;
        data.node_sets = served.sets;
        data.node_errors_mm = served.position_mm;
        if samples.rotation_error_rad.is_some() {
            data.node_orientation_errors_rad = served.orientation_rad;
        }
    }

    let mut content = 0;
    if samples.rotation_error_rad.is_some() {
        content |= CONTENT_ORIENTATION;
    }
    if samples.config.is_some() {
        content |= CONTENT_CONFIG;
    }
    if joint_screen {
        content |= CONTENT_JOINTS;
    }
    if data.model.is_some() {
        content |= CONTENT_MODEL;
    }
    let header = Header {
        version: format::FORMAT_VERSION,
        rkyv_flags: format::RKYV_FLAGS,
        content_flags: content,
        payload_len: 0,
        payload_checksum: 0,
        source_hash,
        method: params,
        grid,
        sample_count: samples.len() as u32,
        joint_radius_rad: plan.joint_radius_rad,
        joint_count: if joint_screen || model.is_some() {
            joint_count as u32
        } else {
            0
        },
        node_set_count: data.node_sets.len() as u32,
        tuning: plan.tuning,
        served_field: if data.node_sets.is_empty() {
            ServedField::Method
        } else {
            plan.served_field
        },
    };
    let bytes = format::encode(header, &data).map_err(|e| BuildError::Encode(e.to_string()))?;
    // Opened once as the runtime will: a table the runtime refuses is never written.
    adwi_runtime::Table::from_vec(&bytes).map_err(BuildError::Unopenable)?;
    report.table_bytes = bytes.len();
    Ok((bytes, report))
}

/// A narrow cell record ([`v2::CellRecord`]): the list inline, or its start in `overflow`.
fn narrow_record(list: &[u32], overflow: &mut Vec<u32>) -> v2::CellRecord {
    let mut record = [0u16; 32];
    record[0] = list.len() as u16;
    if list.len() <= v2::INLINE_CANDIDATES {
        for (slot, &i) in record[1..].iter_mut().zip(list) {
            *slot = i as u16;
        }
    } else {
        let start = overflow.len() as u32;
        record[1] = start as u16;
        record[2] = (start >> 16) as u16;
        overflow.extend_from_slice(list);
    }
    record
}

/// A wide cell record ([`v2::WideCellRecord`]), as [`narrow_record`].
fn wide_record(list: &[u32], overflow: &mut Vec<u32>) -> v2::WideCellRecord {
    let mut record = [0u32; 16];
    record[0] = list.len() as u32;
    if list.len() <= v2::INLINE_CANDIDATES_WIDE {
        record[1..=list.len()].copy_from_slice(list);
    } else {
        record[1] = overflow.len() as u32;
        overflow.extend_from_slice(list);
    }
    record
}

/// What the nodes hold: the method's answer, or the kriging of the samples' errors, which
/// turns with the tool's axis when given one unit axis per sample.
enum NodeField {
    Method,
    Kriging(Option<Vec<[f64; 3]>>),
}

impl NodeField {
    /// Vectors per node ([`ServedField::node_stride`]).
    fn stride(&self) -> usize {
        match self {
            NodeField::Kriging(Some(_)) => 4,
            _ => 1,
        }
    }
}

/// The unit approach (z) axis of the nominal TCP at each sample's joint values: what a
/// served field turning with the tool combines its terms with (the runtime computes the
/// same at the query's joint values).
fn tool_axes(
    samples: &SampleSet,
    model: Option<&PreparedModel>,
) -> Result<Vec<[f64; 3]>, BuildError> {
    let (Some(model), Some(joints)) = (model, &samples.joints) else {
        return Err(BuildError::ToolAxisWithoutModel);
    };
    joints
        .rows()
        .map(|q| {
            model
                .approach_axis(q)
                .ok_or(BuildError::ToolAxisWithoutModel)
        })
        .collect()
}

/// The served tier's node values: the exact method at every node of the grid, per set;
/// `stride` vectors per node (the layout of [`v2::TableData::node_errors_mm`]).
struct NodeValues {
    sets: Vec<v2::NodeSet>,
    /// The first kriging fit's hyperparameters (empty for the method's values).
    kriging_choices: Vec<crate::nugget_kriging::GpChoice>,
    stride: usize,
    position_mm: Vec<[f64; 3]>,
    orientation_rad: Vec<[f64; 3]>,
}

/// One node's vectors: position and orientation, `[f, h_x, h_y, h_z]` (only `f` used at
/// stride 1).
type NodeTerms = ([[f64; 3]; 4], [[f64; 3]; 4]);

impl NodeValues {
    /// Evaluates every node for targets of unknown configuration, then for each
    /// configuration the samples carry (a set equal to an earlier one shares its nodes):
    /// the method's answer where it has one, or the kriging `field` asks for at every
    /// corner of a cell where the exact tier can answer.
    fn compute(
        records: &[SampleRecord],
        params: &MethodParams,
        grid: &Grid,
        lists: &[Vec<u32>],
        samples: &SampleSet,
        field: &NodeField,
    ) -> Result<NodeValues, BuildError> {
        let mut configs: Vec<u8> = samples.config.clone().unwrap_or_default();
        configs.sort_unstable();
        configs.dedup();
        let [nx, ny, nz] = grid.dims.map(|d| d as usize + 1);
        let per_set = nx * ny * nz;
        let stride = field.stride();
        let mut out = NodeValues {
            sets: Vec::new(),
            kriging_choices: Vec::new(),
            stride,
            position_mm: Vec::new(),
            orientation_rad: Vec::new(),
        };
        let missing = [[v2::NO_NODE_VALUE; 3]; 4];
        // Kriging fits, by the samples they were fitted to (one per distinct subset).
        let mut fits: Vec<(Vec<usize>, NodeKriging)> = Vec::new();
        let wanted = std::iter::once(None).chain(configs.into_iter().map(Some));
        for config in wanted {
            let node_position = |node: usize| {
                let ijk = [node % nx, node / nx % ny, node / (nx * ny)];
                (ijk, grid_node_mm(grid, ijk))
            };
            let values: Vec<NodeTerms> = match field {
                NodeField::Method => (0..per_set)
                    .into_par_iter()
                    .map(|node| {
                        let (p, r) =
                            node_value(records, params, grid, lists, node_position(node).0, config);
                        if adwi_runtime::served::is_missing(&p) {
                            (missing, missing)
                        } else {
                            (
                                [p, [0.0; 3], [0.0; 3], [0.0; 3]],
                                [r, [0.0; 3], [0.0; 3], [0.0; 3]],
                            )
                        }
                    })
                    .collect(),
                NodeField::Kriging(axes) => {
                    // The samples a target of this configuration may use (method::select).
                    let seen: Vec<usize> = (0..records.len())
                        .filter(|&i| method::config_matches(records[i].config, config))
                        .collect();
                    let fitted = match fits.iter().position(|(s, _)| *s == seen) {
                        Some(i) => i,
                        None => {
                            let orientation = samples.rotation_error_rad.is_some();
                            let fit =
                                NodeKriging::fit(records, &seen, axes.as_deref(), orientation)?;
                            fits.push((seen.clone(), fit));
                            fits.len() - 1
                        }
                    };
                    let kriging = &fits[fitted].1;
                    if out.kriging_choices.is_empty() {
                        out.kriging_choices = kriging.fit.choices();
                    }
                    let usable =
                        |s: &u32| method::config_matches(records[*s as usize].config, config);
                    (0..per_set)
                        .into_par_iter()
                        .map(|node| {
                            let (ijk, at) = node_position(node);
                            let reached = adjacent_cells(grid, ijk)
                                .any(|cell| lists[cell].iter().any(usable));
                            if reached {
                                kriging.predict(at)
                            } else {
                                (missing, missing)
                            }
                        })
                        .collect()
                }
            };
            let flat =
                |v: &[NodeTerms], which: fn(&NodeTerms) -> &[[f64; 3]; 4]| -> Vec<[f64; 3]> {
                    v.iter()
                        .flat_map(|t| which(t)[..stride].iter().copied())
                        .collect()
                };
            let position = flat(&values, |t| &t.0);
            let orientation = flat(&values, |t| &t.1);
            let first_node = (0..out.sets.len())
                .map(|s| out.sets[s].first_node as usize)
                .find(|&first| {
                    let at = first * stride;
                    position
                        .iter()
                        .zip(&out.position_mm[at..])
                        .all(|(a, b)| same_bits(a, b))
                        && orientation
                            .iter()
                            .zip(&out.orientation_rad[at..])
                            .all(|(a, b)| same_bits(a, b))
                })
                .unwrap_or_else(|| {
                    let first = out.position_mm.len() / stride;
                    out.position_mm.extend(position);
                    out.orientation_rad.extend(orientation);
                    first
                });
            out.sets.push(v2::NodeSet {
                config: config.unwrap_or(CONFIG_UNKNOWN),
                first_node: first_node as u32,
            });
        }
        Ok(out)
    }

    /// The number of cells of the first set whose 8 nodes all have values.
    fn served_cells(&self, grid: &Grid) -> usize {
        let [nx, ny, _] = grid.dims.map(|d| d as usize + 1);
        let has = |i: usize| !adwi_runtime::served::is_missing(&self.position_mm[i * self.stride]);
        (0..grid.cell_count().unwrap_or(0))
            .filter(|&cell| {
                let [i, j, k] = grid.cell_coords(cell);
                let base = i + nx * (j + ny * k);
                [
                    0,
                    1,
                    nx,
                    nx + 1,
                    nx * ny,
                    nx * ny + 1,
                    nx * ny + nx,
                    nx * ny + nx + 1,
                ]
                .iter()
                .all(|&c| has(base + c))
            })
            .count()
    }
}

/// Kriging with a nugget of some samples' errors, in Cartesian distance of their actual
/// positions (where the method places them): position, and orientation when stored;
/// turning with the tool's axis when given the samples' axes.
struct NodeKriging {
    fit: crate::nugget_kriging::ResidualGp,
    orientation: bool,
}

impl NodeKriging {
    fn fit(
        records: &[SampleRecord],
        samples: &[usize],
        axes: Option<&[[f64; 3]]>,
        orientation: bool,
    ) -> Result<NodeKriging, BuildError> {
        let inputs: Vec<Vec<f64>> = samples
            .iter()
            .map(|&i| records[i].actual_mm.to_vec())
            .collect();
        let values: Vec<Vec<f64>> = samples
            .iter()
            .map(|&i| {
                let r = &records[i];
                let mut row = r.error_mm.to_vec();
                if orientation {
                    row.extend_from_slice(&r.rotation_error_rad);
                }
                row
            })
            .collect();
        let fit = match axes {
            Some(axes) => {
                let axes: Vec<[f64; 3]> = samples.iter().map(|&i| axes[i]).collect();
                crate::nugget_kriging::ResidualGp::fit_turning(&inputs, &axes, &values)
            }
            None => crate::nugget_kriging::ResidualGp::fit_cartesian(&inputs, &values),
        }
        .map_err(BuildError::Kriging)?;
        Ok(NodeKriging { fit, orientation })
    }

    /// The field's terms at `position_mm` (`f` alone when it does not turn); orientation
    /// zero when not stored (as the method's).
    fn predict(&self, position_mm: [f64; 3]) -> NodeTerms {
        let t = self
            .fit
            .predict_terms(&position_mm)
            .expect("grid nodes are finite and three-dimensional");
        let vectors = |c: usize| [0, 1, 2, 3].map(|k| [t[c][k], t[c + 1][k], t[c + 2][k]]);
        let rotation = if self.orientation {
            vectors(3)
        } else {
            [[0.0; 3]; 4]
        };
        (vectors(0), rotation)
    }
}

/// The cells (linear indices) node `ijk` is a corner of: up to 8, fewer on the grid's faces.
fn adjacent_cells(grid: &Grid, ijk: [usize; 3]) -> impl Iterator<Item = usize> + '_ {
    let range = move |a: usize| ijk[a].saturating_sub(1)..=ijk[a].min(grid.dims[a] as usize - 1);
    range(2).flat_map(move |k| {
        range(1).flat_map(move |j| range(0).map(move |i| grid.linear_index([i, j, k])))
    })
}

/// The position of node `ijk`, mm.
fn grid_node_mm(grid: &Grid, [i, j, k]: [usize; 3]) -> [f64; 3] {
    [
        grid.origin_mm[0] + i as f64 * grid.cell_mm,
        grid.origin_mm[1] + j as f64 * grid.cell_mm,
        grid.origin_mm[2] + k as f64 * grid.cell_mm,
    ]
}

fn same_bits(a: &[f64; 3], b: &[f64; 3]) -> bool {
    (0..3).all(|i| a[i].to_bits() == b[i].to_bits())
}

/// The exact method at node `ijk` for a target of `config`: through the candidate list of
/// a cell the node is a corner of (a list serves every point of its closed cell), so that
/// the value is the brute-force reference's. Missing ([`v2::NO_NODE_VALUE`]) where no
/// sample is admissible.
fn node_value(
    records: &[SampleRecord],
    params: &MethodParams,
    grid: &Grid,
    lists: &[Vec<u32>],
    [i, j, k]: [usize; 3],
    config: Option<u8>,
) -> ([f64; 3], [f64; 3]) {
    let position = grid_node_mm(grid, [i, j, k]);
    let last = grid.dims.map(|d| d as usize - 1);
    let cell = grid.linear_index([i.min(last[0]), j.min(last[1]), k.min(last[2])]);
    let selection = method::select(params, position, config, lists[cell].iter().copied(), |s| {
        let r = &records[s as usize];
        Some((r.actual_mm, r.config))
    });
    let sample = |s: u32| {
        let r = &records[s as usize];
        (
            r.actual_mm,
            method::norm_mm(r.actual_mm),
            r.measured_error(),
        )
    };
    match method::estimate(params, position, &selection, true, sample) {
        Some(e) => (e.position_error_mm, e.orientation_error_rad),
        None => ([v2::NO_NODE_VALUE; 3], [v2::NO_NODE_VALUE; 3]),
    }
}

/// Samples bucketed by actual position in cubes of edge ≥ ε, so that the samples within ε
/// of a box are found in the buckets the grown box overlaps.
struct SpatialIndex {
    origin_mm: [f64; 3],
    bucket_mm: f64,
    dims: [usize; 3],
    buckets: Vec<Vec<u32>>,
}

impl SpatialIndex {
    fn new(records: &[SampleRecord], radius_mm: f64) -> SpatialIndex {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for r in records {
            for a in 0..3 {
                lo[a] = lo[a].min(r.actual_mm[a]);
                hi[a] = hi[a].max(r.actual_mm[a]);
            }
        }
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        // At most 256 buckets a side, whatever ε.
        let bucket_mm = radius_mm.max(extent / 256.0).max(f64::MIN_POSITIVE);
        let dims = [0, 1, 2].map(|a| ((hi[a] - lo[a]) / bucket_mm) as usize + 1);
        let mut index = SpatialIndex {
            origin_mm: lo,
            bucket_mm,
            dims,
            buckets: vec![Vec::new(); dims[0] * dims[1] * dims[2]],
        };
        for (i, r) in records.iter().enumerate() {
            let b = index.bucket_coords(r.actual_mm);
            let linear = b[0] + dims[0] * (b[1] + dims[1] * b[2]);
            index.buckets[linear].push(i as u32);
        }
        index
    }

    fn bucket_coords(&self, p: [f64; 3]) -> [usize; 3] {
        [0, 1, 2].map(|a| {
            let u = ((p[a] - self.origin_mm[a]) / self.bucket_mm).floor();
            (u.max(0.0) as usize).min(self.dims[a] - 1)
        })
    }

    /// Every sample in a bucket overlapping the box `lo..hi`.
    fn near(&self, lo: [f64; 3], hi: [f64; 3], out: &mut Vec<u32>) {
        let a = self.bucket_coords(lo);
        let b = self.bucket_coords(hi);
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    out.extend_from_slice(&self.buckets[x + self.dims[0] * (y + self.dims[1] * z)]);
                }
            }
        }
    }
}

/// The nearest and farthest distances from `p` to the box `lo..hi`, mm.
fn box_distances(p: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> (f64, f64) {
    let mut near = 0.0;
    let mut far = 0.0;
    for a in 0..3 {
        let below = lo[a] - p[a];
        let above = p[a] - hi[a];
        let gap = below.max(above).max(0.0);
        near += gap * gap;
        let reach = (p[a] - lo[a]).abs().max((hi[a] - p[a]).abs());
        far += reach * reach;
    }
    (near.sqrt(), far.sqrt())
}

/// The candidate list of one cell, sample indices increasing (see the module docs).
/// `joint_screen`: whether the joint-space screen is on, so that no sample is certainly
/// admissible.
fn candidate_list(
    records: &[SampleRecord],
    index: &SpatialIndex,
    params: &MethodParams,
    joint_screen: bool,
    grid: &Grid,
    cell: usize,
) -> Vec<u32> {
    let (lo, hi) = grid.cell_box(grid.cell_coords(cell));
    let lo = lo.map(|v| v - BOX_MARGIN_MM);
    let hi = hi.map(|v| v + BOX_MARGIN_MM);
    let reach = params.radius_mm + DISTANCE_SLACK_MM;
    let mut near = Vec::new();
    index.near(lo.map(|v| v - reach), hi.map(|v| v + reach), &mut near);

    // (sample, nearest, farthest distance to the box).
    let reachable: Vec<(u32, f64, f64)> = near
        .into_iter()
        .filter_map(|i| {
            let (d_near, d_far) = box_distances(records[i as usize].actual_mm, lo, hi);
            (d_near <= reach).then_some((i, d_near, d_far))
        })
        .collect();
    let k = params.max_neighbours as usize;
    let mut list: Vec<u32> =
        if params.has_degree_thresholds() || joint_screen || reachable.len() <= k {
            reachable.iter().map(|&(i, _, _)| i).collect()
        } else {
            // Farthest distances of the samples admissible everywhere in the cell, overall
            // and per configuration, sorted.
            let certain =
                |(_, _, far): &&(u32, f64, f64)| *far <= params.radius_mm - DISTANCE_SLACK_MM;
            let mut all: Vec<f64> = reachable.iter().filter(certain).map(|r| r.2).collect();
            all.sort_by(f64::total_cmp);
            let mut by_config: HashMap<u8, Vec<f64>> = HashMap::new();
            for r in reachable.iter().filter(certain) {
                by_config
                    .entry(records[r.0 as usize].config)
                    .or_default()
                    .push(r.2);
            }
            by_config
                .values_mut()
                .for_each(|v| v.sort_by(f64::total_cmp));
            let nearer =
                |sorted: &[f64], d: f64| sorted.partition_point(|&far| far < d - DISTANCE_SLACK_MM);
            reachable
                .iter()
                .filter(|&&(i, d_near, _)| {
                    let config = records[i as usize].config;
                    let same = by_config.get(&config).map_or(&[][..], Vec::as_slice);
                    nearer(&all, d_near) < k || nearer(same, d_near) < k
                })
                .map(|&(i, _, _)| i)
                .collect()
        };
    // Nearest to the cell's centre first (see `TableData::list_samples`).
    let (lo, hi) = grid.cell_box(grid.cell_coords(cell));
    let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
    let key = |i: u32| method::distance_mm(records[i as usize].actual_mm, centre);
    list.sort_unstable_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
    list
}

#[cfg(test)]
mod tests {
    use super::*;
    use adwi_samples::{parse_samples, ColumnMap};

    #[test]
    fn weights_are_the_papers_unless_given_and_one_implies_the_other() {
        assert_eq!(resolve_weights(None, None), (0.87, 0.13));
        assert_eq!(resolve_weights(Some(0.25), None), (0.25, 0.75));
        assert_eq!(resolve_weights(None, Some(0.25)), (0.75, 0.25));
        assert_eq!(resolve_weights(Some(0.5), Some(0.7)), (0.5, 0.7));
    }

    /// A 3 × 3 × 3 lattice of 100 mm with joint angles, plus `extra` rows.
    fn samples(extra: &str) -> SampleSet {
        let mut csv = String::from("x,y,z,dx,dy,dz,j1,j2,j3,j4,j5,j6\n");
        for i in 0..27 {
            let p = [i % 3, (i / 3) % 3, i / 9].map(|v| 1000.0 + 100.0 * f64::from(v));
            csv += &format!("{},{},{},0.1,0.2,-0.1,{i},0,0,0,0,0\n", p[0], p[1], p[2]);
        }
        csv += extra;
        parse_samples("s.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap()
    }

    fn build(samples: &SampleSet, options: BuildOptions) -> Result<Vec<u8>, BuildError> {
        compile(samples, &options, &|_| {}).map(|(bytes, _)| bytes)
    }

    /// A 5 × 5 × 5 lattice of 100 mm whose errors are a smooth field plus a deterministic
    /// scatter standing in for measurement noise.
    fn noisy_lattice() -> SampleSet {
        let mut csv = String::from("x,y,z,dx,dy,dz\n");
        for i in 0..125 {
            let p = [i % 5, (i / 5) % 5, i / 25].map(|v| 1000.0 + 100.0 * f64::from(v));
            let noise = |k: i32| 0.02 * ((i * 7 + k * 13) % 11 - 5) as f64 / 5.0;
            let smooth = |a: usize| ((p[a] - 1200.0) / 300.0).sin() * 0.3;
            csv += &format!(
                "{},{},{},{},{},{}\n",
                p[0],
                p[1],
                p[2],
                smooth(0) + noise(0),
                smooth(1) + noise(1),
                smooth(2) + noise(2)
            );
        }
        parse_samples("s.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap()
    }

    #[test]
    fn a_kriging_served_field_holds_the_kriging_wherever_the_exact_tier_can_answer() {
        use adwi_runtime::Status;
        let s = noisy_lattice();
        let options = |served_field| BuildOptions {
            served_field,
            ..BuildOptions::default()
        };
        let method =
            adwi_runtime::Table::from_vec(build(&s, options(ServedField::Method)).unwrap())
                .unwrap();
        let kriging = build(&s, options(ServedField::Kriging)).unwrap();
        assert_eq!(kriging, build(&s, options(ServedField::Kriging)).unwrap());
        let kriging = adwi_runtime::Table::from_vec(kriging).unwrap();
        assert_eq!(kriging.header().served_field, ServedField::Kriging);
        assert_eq!(method.header().served_field, ServedField::Method);
        // The reference: the same fit, evaluated directly.
        let records = s.records();
        let inputs: Vec<Vec<f64>> = records.iter().map(|r| r.actual_mm.to_vec()).collect();
        let values: Vec<Vec<f64>> = records.iter().map(|r| r.error_mm.to_vec()).collect();
        let gp = crate::nugget_kriging::ResidualGp::fit_cartesian(&inputs, &values).unwrap();
        let grid = kriging.header().grid;
        let (mut nodes, mut compared, mut smoother) = (0, 0, 0);
        for i in 0..=grid.dims[0] {
            for j in 0..=grid.dims[1] {
                for k in 0..=grid.dims[2] {
                    let at = grid_node_mm(&grid, [i as usize, j as usize, k as usize]);
                    let (m, g) = (method.query(at), kriging.query(at));
                    // The exact tier is the method's in both.
                    assert_eq!(
                        method.exact().query(at).position_error_mm,
                        kriging.exact().query(at).position_error_mm
                    );
                    if m.status == Status::Ok {
                        assert_eq!(g.status, Status::Ok, "the kriging covers less at {at:?}");
                    }
                    if g.status != Status::Ok {
                        continue;
                    }
                    nodes += 1;
                    let want = gp.predict(&at).unwrap();
                    for (got, want) in g.position_error_mm.iter().zip(&want) {
                        assert!((got - want).abs() < 1e-9, "{at:?}");
                    }
                    if m.status != Status::Ok {
                        continue;
                    }
                    // Against the noise-free field, the kriging is the closer one mostly.
                    compared += 1;
                    let truth = [0, 1, 2].map(|a| ((at[a] - 1200.0) / 300.0).sin() * 0.3);
                    let off = |v: [f64; 3]| (0..3).map(|a| (v[a] - truth[a]).abs()).sum::<f64>();
                    if off(g.position_error_mm) < off(m.position_error_mm) {
                        smoother += 1;
                    }
                }
            }
        }
        assert!(compared > 100, "{compared} nodes served by both");
        assert!(nodes > compared, "the kriging serves no fringe node");
        assert!(
            2 * smoother > compared,
            "kriging closer at {smoother} of {compared} nodes"
        );
        // Coverage, against a brute-force reference: a cell is served exactly when each of
        // its 8 corners is a corner of some cell with a sample within ε of its box, and
        // wherever the exact tier answers, the served field does.
        let radius_mm = kriging.method().radius_mm;
        let reached = |cell: [usize; 3]| {
            let (lo, hi) = grid.cell_box(cell);
            records.iter().any(|r| {
                let gap: f64 = (0..3)
                    .map(|a| {
                        (lo[a] - r.actual_mm[a])
                            .max(r.actual_mm[a] - hi[a])
                            .max(0.0)
                    })
                    .map(|d| d * d)
                    .sum();
                gap.sqrt() <= radius_mm
            })
        };
        let dims = grid.dims.map(|d| d as usize);
        let node_reached = |n: [usize; 3]| {
            let around = |a: usize| n[a].saturating_sub(1)..=n[a].min(dims[a] - 1);
            around(0).any(|i| around(1).any(|j| around(2).any(|k| reached([i, j, k]))))
        };
        let mut served = 0;
        for cell in 0..grid.cell_count().unwrap() {
            let c = grid.cell_coords(cell);
            let (lo, _) = grid.cell_box(c);
            let corners_reached =
                (0..8).all(|corner| node_reached([0, 1, 2].map(|a| c[a] + (corner >> a & 1))));
            // Points inside the cell, its centre among them.
            for t in [[0.5; 3], [0.1, 0.9, 0.3], [0.95, 0.05, 0.7]] {
                let at = [0, 1, 2].map(|a| lo[a] + t[a] * grid.cell_mm);
                let answer = kriging.query(at);
                assert_eq!(answer.status == Status::Ok, corners_reached, "at {at:?}");
                if kriging.exact().query(at).status == Status::Ok {
                    assert_eq!(
                        answer.status,
                        Status::Ok,
                        "the exact tier answers at {at:?}"
                    );
                }
            }
            served += usize::from(corners_reached);
        }
        assert!(
            served < grid.cell_count().unwrap(),
            "no cell is left unserved"
        );
    }

    #[test]
    fn a_kriging_served_field_needs_a_served_tier() {
        let s = samples("");
        let options = BuildOptions {
            served_field: ServedField::Kriging,
            joint_radius_deg: Some(10.0),
            ..BuildOptions::default()
        };
        assert!(matches!(
            build(&s, options),
            Err(BuildError::KrigingWithoutServedTier)
        ));
    }

    #[test]
    fn any_radius_with_the_default_bounds_builds_a_table_that_opens() {
        // The default grid grows with ε, so ε never exceeds its diagonal; `compile` opens
        // what it built.
        let s = samples("");
        for radius_mm in [1.0f64, 200.0, 5e4] {
            let options = BuildOptions {
                method: MethodParams::paper(Some(radius_mm)),
                cell_mm: Some(radius_mm.max(100.0) / 2.0),
                ..BuildOptions::default()
            };
            build(&s, options).unwrap();
        }
    }

    #[test]
    fn what_the_runtime_would_refuse_is_refused_before_building() {
        let s = samples("");
        let small_box = Some(([1000.0; 3], [1200.0; 3]));
        let cases = [
            // ε beyond every distance between the grid and the samples.
            BuildOptions {
                method: MethodParams::paper(Some(1e5)),
                bounds_mm: small_box,
                ..BuildOptions::default()
            },
            // The default grid, ε wide, would reach 1e300 mm from the base.
            BuildOptions {
                method: MethodParams::paper(Some(1e300)),
                cell_mm: Some(1e299),
                ..BuildOptions::default()
            },
            BuildOptions {
                method: MethodParams::paper(Some(1e300)),
                ..BuildOptions::default()
            },
            BuildOptions {
                method: MethodParams::paper(Some(f64::MAX)),
                ..BuildOptions::default()
            },
            BuildOptions {
                bounds_mm: Some(([1000.0; 3], [2e6; 3])),
                cell_mm: Some(1e5),
                ..BuildOptions::default()
            },
            BuildOptions {
                joint_radius_deg: Some(800.0),
                ..BuildOptions::default()
            },
        ];
        for options in cases {
            let err = build(&s, options.clone()).unwrap_err();
            assert!(
                matches!(err, BuildError::Implausible(_)),
                "{options:?}: {err}"
            );
        }
        let far = samples("2e6,0,0,0,0,0,0,0,0,0,0,0\n");
        let options = BuildOptions {
            bounds_mm: small_box,
            ..BuildOptions::default()
        };
        let err = build(&far, options).unwrap_err();
        assert!(err.to_string().contains("sample coordinate"), "{err}");
        // A cell so small that every axis counts more cells than u128 holds.
        let options = BuildOptions {
            cell_mm: Some(1e-300),
            bounds_mm: small_box,
            ..BuildOptions::default()
        };
        let err = build(&s, options).unwrap_err();
        assert!(matches!(err, BuildError::TooManyCells { .. }), "{err}");
    }

    #[test]
    fn an_implausible_model_is_refused() {
        use adwi_runtime::chain::Chain;
        use adwi_runtime::kinematics::{MdhJoint, Transform};
        let s = samples("");
        let joint = MdhJoint {
            a_mm: 100.0,
            d_mm: 200.0,
            ..MdhJoint::default()
        };
        let chain = |base: Transform| {
            Chain::from_mdh(base, &[joint; 6], Transform::IDENTITY, None).unwrap()
        };
        let nominal = chain(Transform::IDENTITY);
        let plan = plan(&s, &BuildOptions::default()).unwrap();
        let hash = s.source_hash();
        let sound = PreparedModel::new(nominal, nominal).unwrap();
        compile_plan(&s, &plan, Some(&sound), hash, &|_| {}).unwrap();
        let far = Transform {
            translation_mm: [1e300, 0.0, 0.0],
            ..Transform::IDENTITY
        };
        let model = PreparedModel::new(nominal, chain(far)).unwrap();
        let err = compile_plan(&s, &plan, Some(&model), hash, &|_| {}).unwrap_err();
        assert!(matches!(err, BuildError::Implausible(_)), "{err}");
    }
}
