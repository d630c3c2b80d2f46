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
//! neighbouring cell, still finds every sample it needs. Identical lists are stored once.
//! Each cell also stores the base weights `q_i` at its centre.
//!
//! Cells are processed in parallel; results are assembled in cell order, so the bytes
//! written do not depend on the number of threads.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};

use adwi_runtime::format::{
    self, CellRecord, Grid, Header, KinematicModel, SampleRecord, TableData, CONTENT_CONFIG,
    CONTENT_JOINTS, CONTENT_MODEL, CONTENT_ORIENTATION,
};
use adwi_runtime::method::{self, MethodParams};
use rayon::prelude::*;

use crate::samples::SampleSet;

/// Cell boxes are grown by this much (mm) when computing candidate lists.
pub const BOX_MARGIN_MM: f64 = 1e-6;
/// Slack (mm) in every distance comparison that decides a candidate list.
pub const DISTANCE_SLACK_MM: f64 = 1e-9;
/// The most cells a table may have.
pub const MAX_CELLS: usize = 20_000_000;
/// The default radius ε is this many sample spacings: it covers the 8 corners of a lattice
/// cube (at most √3 spacings away) from any point inside it.
pub const RADIUS_PER_SPACING: f64 = 2.0;
/// The default cell edge is the sample spacing divided by this.
pub const CELLS_PER_SPACING: f64 = 4.0;

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
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            method: MethodParams::paper(None),
            cell_mm: None,
            bounds_mm: None,
            joint_radius_deg: None,
        }
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
    #[error("a hybrid table needs samples with joint angles (columns j1..j6)")]
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
    if joint_radius_rad > 0.0 && samples.joints.is_none() {
        return Err(BuildError::Params(
            "a joint radius needs samples with joint angles (columns j1..j6)",
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
    model: Option<KinematicModel>,
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
    };
    if let Some(model) = &model {
        format::check_model_plausible(model)?;
    }
    let joint_screen = plan.joint_radius_rad > 0.0;
    let records = samples.records();
    let index = SpatialIndex::new(&records, params.radius_mm);
    let done = AtomicU64::new(0);
    let per_cell: Vec<CellPlan> = (0..plan.cells())
        .into_par_iter()
        .map(|cell| {
            let candidates = candidate_list(&records, &index, &params, joint_screen, &grid, cell);
            let centre = centre_weights(&records, &params, &grid, cell, &candidates);
            if done.fetch_add(1, Ordering::Relaxed) % 4096 == 4095 {
                progress(4096);
            }
            (candidates, centre)
        })
        .collect();
    progress(done.load(Ordering::Relaxed) % 4096);

    let mut data = TableData {
        actual_norms_mm: records
            .iter()
            .map(|r| method::norm_mm(r.actual_mm))
            .collect(),
        samples: records,
        cells: Vec::with_capacity(plan.cells()),
        centre_offsets: Vec::with_capacity(plan.cells() + 1),
        list_samples: Vec::new(),
        centre_samples: Vec::new(),
        centre_weights: Vec::new(),
        joints_rad: match &samples.joints {
            Some(j) if j.count() == format::JOINT_COUNT => {
                j.rows().map(|q| std::array::from_fn(|a| q[a])).collect()
            }
            Some(j) => {
                return Err(BuildError::JointCount {
                    model: format::JOINT_COUNT,
                    samples: j.count(),
                })
            }
            None => Vec::new(),
        },
        model,
    };
    // Identical lists are stored once, in order of first appearance.
    let mut starts: HashMap<&[u32], u32> = HashMap::new();
    data.centre_offsets.push(0);
    for (list, centre) in &per_cell {
        let list_start = *starts.entry(list.as_slice()).or_insert_with(|| {
            let start = data.list_samples.len() as u32;
            data.list_samples.extend_from_slice(list);
            start
        });
        data.cells.push(CellRecord {
            list_start,
            list_len: list.len() as u32,
        });
        for &(sample, q) in centre {
            data.centre_samples.push(sample);
            data.centre_weights.push(q);
        }
        data.centre_offsets.push(data.centre_samples.len() as u32);
        if !list.is_empty() {
            report.cells_covered += 1;
            report.max_list_len = report.max_list_len.max(list.len());
            report.mean_list_len += list.len() as f64;
        }
    }
    report.mean_list_len /= report.cells_covered.max(1) as f64;
    report.distinct_lists = starts.len();
    report.list_entries = data.list_samples.len();

    let mut content = 0;
    if samples.rotation_error_rad.is_some() {
        content |= CONTENT_ORIENTATION;
    }
    if samples.config.is_some() {
        content |= CONTENT_CONFIG;
    }
    if samples.joints.is_some() {
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
    };
    let bytes = format::encode(header, &data).map_err(|e| BuildError::Encode(e.to_string()))?;
    // Opened once as the runtime will: a table the runtime refuses is never written.
    adwi_runtime::Table::from_vec(&bytes).map_err(BuildError::Unopenable)?;
    report.table_bytes = bytes.len();
    Ok((bytes, report))
}

/// One cell's candidate list and base weights `(sample, q)`, before assembly.
type CellPlan = (Vec<u32>, Vec<(u32, f64)>);

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

/// The neighbours and weights at a cell's centre, through the runtime's own selection.
fn centre_weights(
    records: &[SampleRecord],
    params: &MethodParams,
    grid: &Grid,
    cell: usize,
    candidates: &[u32],
) -> Vec<(u32, f64)> {
    let (lo, hi) = grid.cell_box(grid.cell_coords(cell));
    let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
    let selection = method::select(params, centre, None, candidates.iter().copied(), |i| {
        let r = &records[i as usize];
        Some((r.actual_mm, r.config))
    });
    let error_of = |i: u32| records[i as usize].measured_error();
    let neighbours = method::neighbours(centre, &selection, |i| records[i as usize].actual_mm);
    match method::predict(params, neighbours.as_slice(), error_of) {
        Some(p) => p
            .neighbours
            .as_slice()
            .iter()
            .zip(p.weights.as_slice())
            .map(|(n, &q)| (n.sample, q))
            .collect(),
        None => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::samples::{parse_samples, ColumnMap};

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
        let s = samples("");
        let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let params = format::ModelParams {
            joints: [[100.0, 200.0, 0.0, 0.0, 0.0]; 6],
            tool: identity,
            base: identity,
        };
        let mut model = KinematicModel {
            nominal: params,
            calibrated: params,
        };
        let plan = plan(&s, &BuildOptions::default()).unwrap();
        let hash = s.source_hash();
        compile_plan(&s, &plan, Some(model), hash, &|_| {}).unwrap();
        model.calibrated.base[3] = 1e300;
        let err = compile_plan(&s, &plan, Some(model), hash, &|_| {}).unwrap_err();
        assert!(matches!(err, BuildError::Implausible(_)), "{err}");
        model.calibrated.base[3] = 0.0;
        model.nominal.tool[0] = 2.0;
        let err = compile_plan(&s, &plan, Some(model), hash, &|_| {}).unwrap_err();
        assert!(matches!(err, BuildError::Implausible(_)), "{err}");
    }
}
