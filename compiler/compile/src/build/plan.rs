//! Planning a build: its options resolved against its samples into a [`Plan`] — ε, the
//! cell edge and the grid derived where not given — and every check the runtime will make
//! of them, with the table's size estimated, before any work.

use adwi_runtime::format::{self, Grid};
use adwi_runtime::method::MethodParams;

use super::merge::{merged_count, Merging, SampleMerge, MERGE_FRACTIONS};
use super::{BuildError, BuildOptions, ServedField, Tuning};
use adwi_samples::SampleSet;

/// The most cells a table may have.
pub const MAX_CELLS: usize = 20_000_000;
/// The default radius ε is this many sample spacings: it covers the 8 corners of a lattice
/// cube (at most √3 spacings away) from any point inside it.
pub const RADIUS_PER_SPACING: f64 = 2.0;
/// The default cell edge is the sample spacing divided by this: cells half a spacing wide
/// keep a cell's candidates within one 64-byte record for lattice-like samples, and put
/// the served field's nodes twice as dense as the samples.
pub const CELLS_PER_SPACING: f64 = 2.0;
/// The most a table with a derived cell edge is estimated to take ([`Plan::estimated_table_bytes`]),
/// bytes: the cell grows beyond spacing / [`CELLS_PER_SPACING`] until its table fits, so
/// that dense data (a hundred thousand samples, a tracker's repeated poses) give a table
/// of the workspace's size rather than of the sample count's.
pub const MAX_DERIVED_TABLE_BYTES: u128 = 64_000_000;
/// Samples whose volume spacing ([`derivation_spacing_mm`]) exceeds their nearest-neighbour
/// spacing by more than this are clustered: the derived ε and cell follow the volume.
pub const CLUSTERED_SPACINGS: f64 = 4.0;

/// A build resolved from its options and samples, once: every parameter the table will
/// hold, and what was derived. [`compile_plan`](super::compile_plan) consumes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// The method's parameters, ε resolved.
    pub params: MethodParams,
    /// The cell grid.
    pub grid: Grid,
    /// The joint-space admissibility radius, rad (0 = off).
    pub joint_radius_rad: f64,
    /// The sample spacing ε and the cell were derived from, mm ([`derivation_spacing_mm`]).
    pub spacing_mm: Option<f64>,
    /// Whether ε was derived from the spacing.
    pub radius_derived: bool,
    /// Whether the cell edge was derived from the spacing.
    pub cell_derived: bool,
    /// The number of samples planned for (measured).
    pub samples: usize,
    /// Whether the samples are merged in voxels before the table is built, and the count
    /// left ([`super::merge`]): `None` keeps every sample.
    pub merge: Option<SampleMerge>,
    /// The cross-validation that chose the options, for the header.
    pub tuning: Option<Tuning>,
    /// Bytes of served values per node of the grid, at most (the estimate's).
    pub node_bytes: u128,
    /// What the served tier's nodes hold, as asked; in a [`super::BuildReport`], as
    /// written (a kriging asked of a hybrid table turns with the tool only where the
    /// likelihood gives that part weight).
    pub served_field: ServedField,
    /// A kriging field's hyperparameters, when given ([`BuildOptions::kriging_choices`]).
    pub kriging_choices: Option<crate::nugget_kriging::GivenChoices>,
    /// Whether a hybrid table gets a posture term ([`BuildOptions::posture`]).
    pub posture: crate::posture::Posture,
    /// Where the samples' measured point is on the flange, when a robot file says
    /// (recorded as the table's evidence, so that a query can name another TCP); `None`
    /// from [`plan`], set by a hybrid build.
    pub point_in_flange: Option<adwi_runtime::format::PointInFlange>,
}

impl Plan {
    /// The number of cells in the grid.
    pub fn cells(&self) -> usize {
        self.grid.cell_count().unwrap_or(0)
    }

    /// The number of samples the table holds: the measured ones, or their voxel averages.
    pub fn table_samples(&self) -> usize {
        self.merge.map_or(self.samples, |m| m.merged)
    }

    /// At most how many cells can hold candidates ([`max_covered_cells`]).
    pub fn coverable_cells(&self) -> f64 {
        max_covered_cells(
            self.table_samples(),
            self.params.radius_mm,
            self.grid.cell_mm,
        )
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
            self.grid.dims.map(u128::from),
            self.table_samples(),
            self.params.radius_mm,
            self.grid.cell_mm,
            self.params.max_neighbours,
            self.node_bytes,
        )
    }
}

/// Bytes of the served field's nodes per node of the grid, at most: 24 per vector, times
/// the vectors per node (4 for a kriging that may turn with the tool: one asked of samples
/// with joint angles, which a hybrid table has), twice with orientation, once per node set
/// (targets of unknown configuration, and each configuration); 0 with a joint screen,
/// which has no served tier.
fn node_bytes(samples: &SampleSet, served_field: ServedField, joint_screen: bool) -> u128 {
    if joint_screen {
        return 0;
    }
    let stride = match served_field {
        ServedField::Method => 1,
        ServedField::Kriging | ServedField::KrigingToolAxis if samples.joints.is_some() => 4,
        ServedField::Kriging | ServedField::KrigingToolAxis => 1,
    };
    let orientation = if samples.rotation_error_rad.is_some() {
        2
    } else {
        1
    };
    let mut configs: Vec<u8> = samples.config.clone().unwrap_or_default();
    configs.sort_unstable();
    configs.dedup();
    24 * stride * orientation * (1 + configs.len() as u128)
}

/// A table's size before it is built, bytes, for a grid `dims` cells wide: per cell its
/// 8-byte record and base-weight offset, per cell that can be covered
/// ([`max_covered_cells`]) at most `k` base weights (12 bytes each), per node
/// `node_bytes` of served values, and per sample its record.
pub fn estimated_table_bytes(
    dims: [u128; 3],
    samples: usize,
    radius_mm: f64,
    cell_mm: f64,
    k: u32,
    node_bytes: u128,
) -> u128 {
    // Saturating: an absurd grid (a huge --radius, say) must be refused, not overflow.
    let count = |d: [u128; 3]| d.iter().fold(1u128, |p, &d| p.saturating_mul(d));
    let cells = count(dims);
    let nodes = count(dims.map(|d| d.saturating_add(1)));
    let covered = (max_covered_cells(samples, radius_mm, cell_mm) as u128).min(cells);
    cells
        .saturating_mul(12)
        .saturating_add(covered.saturating_mul(12 * u128::from(k)))
        .saturating_add(nodes.saturating_mul(node_bytes))
        .saturating_add(samples as u128 * 120)
}

/// The spacing a default ε and cell are derived from, mm: the median nearest-neighbour
/// distance of the nominal positions ([`SampleSet::spacing_mm`]), unless the volume per
/// sample says the samples are clustered. For samples spread through a volume, a lattice
/// or a random cloud, the volume spacing `(V / n)^(1/3)` (`V` the nominal bounding box's
/// volume) is one to two nearest-neighbour spacings; far above that
/// ([`CLUSTERED_SPACINGS`]) the samples come in clusters (one pose measured in several
/// orientations, passes of a tracked path), their nearest neighbour measures the cluster,
/// not the volume between clusters that ε must span, and the volume spacing is used.
/// Samples on a plane or a line have no volume, and keep their nearest neighbour.
pub fn derivation_spacing_mm(samples: &SampleSet) -> Option<f64> {
    let nearest = samples.spacing_mm()?;
    let (lo, hi) = samples.nominal_bounds_mm()?;
    let volume: f64 = (0..3).map(|a| hi[a] - lo[a]).product();
    let per_sample = (volume / samples.len() as f64).cbrt();
    Some(if per_sample > CLUSTERED_SPACINGS * nearest {
        per_sample
    } else {
        nearest
    })
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

/// Checks every option that does not depend on the samples (the method's parameters, a
/// given ε, cell and bounds, the joint screen and the terms it excludes), so that a build
/// refuses them before it reads a file. [`plan`] checks them again with what the samples
/// derive.
///
/// # Errors
///
/// The first option out of range, or a combination that cannot be built.
pub fn check_options(options: &BuildOptions) -> Result<(), BuildError> {
    // A derived ε is checked by `plan`; any positive stand-in checks the other parameters.
    let params = options
        .method
        .with_radius(options.method.radius_mm.unwrap_or(1.0));
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
    if joint_radius_rad > 0.0 && options.posture != crate::posture::Posture::Off {
        return Err(BuildError::PostureWithoutModel);
    }
    if let crate::posture::Posture::Given(p) = options.posture {
        let positive = |v: f64| v > 0.0 && v.is_finite();
        if !(positive(p.radius_mm) && positive(p.length_rad) && positive(p.floor)) {
            return Err(BuildError::Params(
                "the posture term's radius, length and floor must be positive and finite",
            ));
        }
    }
    if options.max_table_bytes == Some(0) {
        return Err(BuildError::Params(
            "the table's bound must be positive and finite",
        ));
    }
    if let Some(voxel_mm) = options.merge_voxel_mm.filter(|v| *v != 0.0) {
        check_merge_voxel(recordable_voxel_mm(voxel_mm))?;
        if options.posture != crate::posture::Posture::Off {
            return Err(BuildError::Params(
                "a posture term holds every sample: its table cannot merge them",
            ));
        }
    }
    if let Some(cell_mm) = options.cell_mm {
        if !(cell_mm.is_finite() && cell_mm > 0.0) {
            return Err(BuildError::Params("cell size must be finite and positive"));
        }
    }
    if let Some((lo, hi)) = options.bounds_mm {
        if !(0..3).all(|a| lo[a].is_finite() && hi[a].is_finite() && lo[a] < hi[a]) {
            return Err(BuildError::Bounds(format!(
                "{lo:?} to {hi:?}: each minimum must be below its maximum, all finite"
            )));
        }
        for v in lo.iter().chain(&hi) {
            format::check_coordinate("a grid bound (mm)", *v)?;
        }
    }
    Ok(())
}

/// Resolves a build's options against its samples: derives ε, the cell edge and the grid
/// where not given, and checks everything the runtime will check, before any work.
///
/// # Errors
///
/// Parameters out of range, underivable defaults, a grid too large or implausible.
pub fn plan(samples: &SampleSet, options: &BuildOptions) -> Result<Plan, BuildError> {
    let spacing_mm = derivation_spacing_mm(samples);
    let derive = |what| {
        spacing_mm
            .filter(|s| *s > 0.0)
            .ok_or(BuildError::CannotDerive(what))
    };
    let radius_mm = match options.method.radius_mm {
        Some(r) => r,
        None => RADIUS_PER_SPACING * derive("the radius")?,
    };
    check_options(options)?;
    let params = options.method.with_radius(radius_mm);
    params.validate().map_err(BuildError::Params)?;
    let joint_radius_rad = options.joint_radius_deg.unwrap_or(0.0).to_radians();
    if joint_radius_rad > 0.0 && samples.joints.is_none() {
        return Err(BuildError::Params(
            "a joint radius needs samples with joint angles (columns j1..jn)",
        ));
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
    let node_bytes = node_bytes(samples, options.served_field, joint_radius_rad > 0.0);
    // Cells per axis; saturating: a tiny cell makes each count reach u128::MAX (`as`
    // saturates).
    let dims_for = |cell_mm: f64| [0, 1, 2].map(|a| ((hi[a] - lo[a]) / cell_mm).ceil().max(1.0));
    let estimate_with = |cell_mm: f64, table_samples: usize| {
        estimated_table_bytes(
            dims_for(cell_mm).map(|d| d as u128),
            table_samples,
            radius_mm,
            cell_mm,
            params.max_neighbours,
            node_bytes,
        )
    };
    let (cell_mm, merge) = match options.cell_mm {
        Some(c) => (c, given_merge(samples, options.merge_voxel_mm)?),
        None => {
            let spacing_mm = derive("the cell size")?;
            let fine = spacing_mm / CELLS_PER_SPACING;
            // Cells beyond the grid's largest extent make it no smaller: what a table of
            // one cell per axis takes is the samples' own part, which no cell shrinks.
            let extent = (0..3).map(|a| hi[a] - lo[a]).fold(fine, f64::max);
            // The smallest cell whose table, of `n` samples, is estimated within the
            // bound, which is never below twice the samples' own part (samples too many
            // for 64 MB whatever the cell, and not merged).
            let bound = options.max_table_bytes.unwrap_or(MAX_DERIVED_TABLE_BYTES);
            let cell_for = |n: usize| {
                let budget = bound.max(estimate_with(extent, n).saturating_mul(2));
                if estimate_with(fine, n) <= budget {
                    fine
                } else {
                    smallest_cell_within(fine, extent, |c| estimate_with(c, n) <= budget)
                }
            };
            // What a table of `merged` samples takes with cells of `cell_mm`.
            let predicted = |merged: &SampleSet, cell_mm: f64| {
                let grid = Grid {
                    origin_mm: lo,
                    cell_mm,
                    dims: dims_for(cell_mm).map(|d| d as u32),
                };
                let node_bytes = predicted_node_bytes(merged, options.served_field);
                predicted_table_bytes(merged, &params, &grid, node_bytes, joint_radius_rad > 0.0)
            };
            // The cell every sample would have: a merge keeps it (the served tier's grid
            // as before) where it can.
            let cell_mm = cell_for(samples.len());
            // Up to 65,535 samples whose own part fits, the estimate alone sizes the
            // table (as it always has); beyond, or with a bound given, the table's size is
            // predicted, and samples it cannot hold are merged.
            let checked = options.max_table_bytes.is_some()
                || samples.len() > adwi_runtime::format::v2::NARROW_SAMPLES
                || estimate_with(extent, samples.len()).saturating_mul(2) > bound;
            match options.merge_voxel_mm {
                None if !checked => (cell_mm, None),
                // A posture term holds every sample's joints and residual: its table keeps
                // them all.
                None if options.posture != crate::posture::Posture::Off => (cell_mm, None),
                None if own_bytes(samples, samples.len()) <= bound
                    && predicted(samples, cell_mm) <= bound =>
                {
                    (cell_mm, None)
                }
                None => {
                    // The served tier's grid kept; else the cell grown with the merged
                    // samples, as for samples that few. Each voxel's count is sorted for
                    // once.
                    let mut counts = [None; MERGE_FRACTIONS.len()];
                    let kept = bounded_merge(samples, spacing_mm, bound, &mut counts, |merged| {
                        predicted(merged, cell_mm) <= bound
                    });
                    let merge = kept.or_else(|| {
                        bounded_merge(samples, spacing_mm, bound, &mut counts, |merged| {
                            predicted(merged, cell_for(merged.len())) <= bound
                        })
                    });
                    match (merge, options.max_table_bytes) {
                        (None, Some(max_bytes)) => {
                            let coarsest = MERGE_FRACTIONS.len() - 1;
                            let voxel_mm =
                                recordable_voxel_mm(spacing_mm * MERGE_FRACTIONS[coarsest]);
                            let merged =
                                counts[coarsest].unwrap_or_else(|| merged_count(samples, voxel_mm));
                            return Err(BuildError::TableBound {
                                samples: samples.len(),
                                voxel_mm,
                                merged,
                                merged_bytes: own_bytes(samples, merged),
                                max_bytes,
                            });
                        }
                        (None, None) => (cell_mm, None),
                        (Some(m), _) if kept.is_some() => (cell_mm, Some(m)),
                        (Some(m), _) => (cell_for(m.merged), Some(m)),
                    }
                }
                given => (cell_mm, given_merge(samples, given)?),
            }
        }
    };
    let table_samples = merge.map_or(samples.len(), |m| m.merged);
    let estimate = |cell_mm: f64| estimate_with(cell_mm, table_samples);
    if !(cell_mm.is_finite() && cell_mm > 0.0) {
        return Err(BuildError::Params("cell size must be finite and positive"));
    }
    let dims_f = dims_for(cell_mm);
    let cells = dims_f
        .iter()
        .fold(1u128, |product, &d| product.saturating_mul(d as u128));
    if cells > MAX_CELLS as u128 || dims_f.iter().any(|&d| d > u32::MAX as f64) {
        return Err(BuildError::TooManyCells {
            cells,
            cell_mm,
            estimated_bytes: estimate(cell_mm),
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
        merge,
        tuning: options.tuning,
        served_field: options.served_field,
        kriging_choices: options.kriging_choices,
        posture: options.posture,
        node_bytes,
        point_in_flange: None,
    })
}

/// The finest voxel of [`MERGE_FRACTIONS`] of `spacing_mm` whose merged samples' table
/// `fits` ([`super::merge`]); none when even the coarsest leaves too many (samples a
/// spacing apart are not redundant). A count of merged samples whose own part (header and
/// per-sample bytes, which every table of them holds whatever its cell) already exceeds
/// `bound` is neither merged nor predicted: no table of them fits.
fn bounded_merge(
    samples: &SampleSet,
    spacing_mm: f64,
    bound: u128,
    counts: &mut [Option<usize>; MERGE_FRACTIONS.len()],
    fits: impl Fn(&SampleSet) -> bool,
) -> Option<SampleMerge> {
    // The voxels nest (each edge twice the last, on one origin), so the coarsest leaves the
    // fewest samples: when even their own part exceeds the bound, no voxel's table fits,
    // and the refusal costs one count, not five.
    let coarsest = counts.len() - 1;
    let fewest = *counts[coarsest].get_or_insert_with(|| {
        let voxel_mm = recordable_voxel_mm(spacing_mm * MERGE_FRACTIONS[coarsest]);
        merged_count(samples, voxel_mm)
    });
    if own_bytes(samples, fewest) > bound {
        return None;
    }
    // A voxel that merges no more than the last one tried fits no better: not predicted
    // again (samples a spacing apart are refused in a fraction of a second).
    let mut tried = samples.len();
    MERGE_FRACTIONS
        .iter()
        .zip(counts)
        .find_map(|(fraction, known)| {
            let voxel_mm = recordable_voxel_mm(spacing_mm * fraction);
            let mut merging = None;
            let count = *known
                .get_or_insert_with(|| merging.insert(Merging::new(samples, voxel_mm)).count());
            let hopeless = count == tried || own_bytes(samples, count) > bound;
            tried = count;
            if hopeless {
                return None;
            }
            let merged = merging
                .unwrap_or_else(|| Merging::new(samples, voxel_mm))
                .merge();
            fits(&merged).then_some(SampleMerge {
                voxel_mm,
                measured: samples.len(),
                merged: merged.len(),
            })
        })
}

/// Bytes every table of `count` of these samples holds whatever its grid: the header and
/// each sample's position and errors ([`predicted_table_bytes`] without cells, candidate
/// lists or nodes), a lower bound of its size.
fn own_bytes(samples: &SampleSet, count: usize) -> u128 {
    format::HEADER_LEN as u128 + count as u128 * per_sample_bytes(samples, false)
}

/// Bytes of one sample in a table: its query block and position error, its orientation
/// error when the samples carry them, its configuration, its joint values with a screen.
fn per_sample_bytes(samples: &SampleSet, joint_screen: bool) -> u128 {
    32 + 24
        + if samples.rotation_error_rad.is_some() {
            24
        } else {
            0
        }
        + u128::from(samples.config.is_some())
        + if joint_screen {
            8 * samples.joint_count().unwrap_or(0) as u128
        } else {
            0
        }
}

/// Bytes of the served field's nodes per node of the grid, as a table of `samples` with
/// `served_field` writes them: 24 per vector, one vector per node (four for
/// [`ServedField::KrigingToolAxis`] asked), twice with orientation, one node set (sets of
/// equal values share their nodes: a single configuration's is the set of every sample),
/// else one per configuration and one for targets of unknown configuration. A hybrid
/// table's kriging that turns with the tool where the likelihood says takes four vectors
/// a node, which this does not foresee.
pub fn predicted_node_bytes(samples: &SampleSet, served_field: ServedField) -> u128 {
    let stride = served_field.node_stride() as u128;
    let orientation = if samples.rotation_error_rad.is_some() {
        2
    } else {
        1
    };
    let mut configs: Vec<u8> = samples.config.clone().unwrap_or_default();
    configs.sort_unstable();
    configs.dedup();
    let sets = if configs.len() <= 1 {
        1
    } else {
        1 + configs.len() as u128
    };
    24 * stride * orientation * sets
}

/// Cells whose candidate lists [`predicted_table_bytes`] computes, at most: a few
/// thousand, evenly strided, predict the lists' bytes to a per cent or two.
const PREDICTION_CELLS: usize = 4096;

/// What a table of `samples` on `grid` takes, bytes, predicted before it is built: its
/// cell records, the samples' query blocks and errors, the served nodes at `node_bytes`
/// each ([`predicted_node_bytes`]; none with a joint screen), and the long candidate lists' overflow, computed for every few hundredth
/// cell and scaled ([`super::candidates::predicted_overflow_bytes`]).
pub fn predicted_table_bytes(
    samples: &SampleSet,
    params: &MethodParams,
    grid: &Grid,
    node_bytes: u128,
    joint_screen: bool,
) -> u128 {
    let cells = grid.cell_count().unwrap_or(usize::MAX) as u128;
    let nodes = grid
        .dims
        .iter()
        .map(|&d| u128::from(d) + 1)
        .product::<u128>();
    let per_sample = per_sample_bytes(samples, joint_screen);
    let records = samples.records();
    let stride = (cells as usize).div_ceil(PREDICTION_CELLS);
    let overflow =
        super::candidates::predicted_overflow_bytes(&records, params, joint_screen, grid, stride);
    format::HEADER_LEN as u128
        + cells * 64
        + overflow
        + samples.len() as u128 * per_sample
        + if joint_screen { 0 } else { nodes * node_bytes }
}

/// A merge asked for ([`BuildOptions::merge_voxel_mm`]): none for 0 (or not asked), else
/// the voxel as the header records it.
fn given_merge(
    samples: &SampleSet,
    voxel_mm: Option<f64>,
) -> Result<Option<SampleMerge>, BuildError> {
    match voxel_mm {
        None => Ok(None),
        Some(0.0) => Ok(None),
        Some(v) => {
            let voxel_mm = recordable_voxel_mm(v);
            check_merge_voxel(voxel_mm)?;
            Ok(Some(SampleMerge {
                voxel_mm,
                measured: samples.len(),
                merged: merged_count(samples, voxel_mm),
            }))
        }
    }
}

/// `voxel_mm` as the header's `f32` holds it, so that the voxel merged with is the one
/// recorded.
fn recordable_voxel_mm(voxel_mm: f64) -> f64 {
    voxel_mm as f32 as f64
}

/// A merge voxel the runtime accepts: within [`format::MIN_MERGE_VOXEL_MM`] and the
/// workspace bound.
fn check_merge_voxel(voxel_mm: f64) -> Result<(), BuildError> {
    // Written so that NaN fails the test.
    if (format::MIN_MERGE_VOXEL_MM..=format::MAX_COORDINATE_MM).contains(&voxel_mm) {
        Ok(())
    } else {
        Err(BuildError::Params(
            "the merge voxel must be 0 (no merge) or within 1e-6 to 1e6 mm",
        ))
    }
}

/// The smallest cell edge above `fine` that `fits` (to a thousandth of itself), for a
/// `fits` that holds from some edge on: doubled until it fits (or reaches `largest`, the
/// edge of a grid of one cell per axis, beyond which nothing shrinks), then bisected; the
/// steps are fixed, so the edge is the same on every machine.
fn smallest_cell_within(fine: f64, largest: f64, fits: impl Fn(f64) -> bool) -> f64 {
    let mut high = fine;
    while !fits(high) && high < largest {
        high = (high * 2.0).min(largest);
    }
    let mut low = high / 2.0;
    while high - low > 1e-3 * high {
        let middle = 0.5 * (low + high);
        if fits(middle) {
            high = middle;
        } else {
            low = middle;
        }
    }
    high
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::fixtures::{build, samples};

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
        // Beyond the kilometre a sample file may hold (the reader refuses it), so set here.
        let mut far = samples("");
        far.nominal_mm[0] = [2e6, 0.0, 0.0];
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
    fn a_derived_cell_keeps_any_sample_count_within_the_table_bound() {
        use rand::{Rng, SeedableRng};
        // 128,000 random samples in the KR150-2's box: the spacing alone would give 3 mm
        // cells and a table of hundreds of megabytes.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut csv = String::from("x,y,z,dx,dy,dz\n");
        for _ in 0..128_000 {
            let x = rng.gen_range(1350.0..2150.0);
            let y = rng.gen_range(50.0..850.0);
            let z = rng.gen_range(850.0..1650.0);
            csv += &format!("{x},{y},{z},0.1,{},-0.2\n", rng.gen_range(-0.05..0.05));
        }
        let s = adwi_samples::parse_samples(
            "s.csv".as_ref(),
            csv.as_bytes(),
            &adwi_samples::ColumnMap::default(),
        )
        .unwrap();
        // A random cloud is not clustered: its nearest neighbour is its spacing.
        assert_eq!(derivation_spacing_mm(&s), s.spacing_mm());
        let plan = plan(&s, &BuildOptions::default()).unwrap();
        let fine = s.spacing_mm().unwrap() / CELLS_PER_SPACING;
        assert!(plan.cell_derived && plan.grid.cell_mm > fine, "{plan:?}");
        assert!(plan.estimated_table_bytes() <= MAX_DERIVED_TABLE_BYTES);
        // The smallest such cell: a cell 1 % finer would not fit.
        let finer = BuildOptions {
            cell_mm: Some(plan.grid.cell_mm / 1.01),
            ..BuildOptions::default()
        };
        let finer = super::plan(&s, &finer).unwrap();
        assert!(finer.estimated_table_bytes() > MAX_DERIVED_TABLE_BYTES);
        let (bytes, report) = crate::build::compile(&s, &BuildOptions::default(), &|_| {}).unwrap();
        assert!(
            (bytes.len() as u128) <= MAX_DERIVED_TABLE_BYTES,
            "{} bytes, {report:?}",
            bytes.len()
        );
        // Sparse samples keep the spacing's cell.
        let lattice = samples("");
        let plan = super::plan(&lattice, &BuildOptions::default()).unwrap();
        assert_eq!(plan.grid.cell_mm, 100.0 / CELLS_PER_SPACING);
    }

    #[test]
    fn clustered_samples_derive_from_the_volume_between_clusters() {
        // A 4 × 4 × 4 lattice of 100 mm, each point measured in 10 poses 0.5 mm apart: the
        // nearest neighbour is 0.5 mm, the volume spacing about 70 mm.
        let mut csv = String::from("x,y,z,dx,dy,dz\n");
        for i in 0..64 {
            for r in 0..10 {
                let p = [i % 4, (i / 4) % 4, i / 16].map(|v| 1000.0 + 100.0 * f64::from(v));
                csv += &format!(
                    "{},{},{},0.1,0.1,0.1\n",
                    p[0] + 0.5 * f64::from(r),
                    p[1],
                    p[2]
                );
            }
        }
        let s = adwi_samples::parse_samples(
            "s.csv".as_ref(),
            csv.as_bytes(),
            &adwi_samples::ColumnMap::default(),
        )
        .unwrap();
        assert_eq!(s.spacing_mm(), Some(0.5));
        let spacing = derivation_spacing_mm(&s).unwrap();
        let volume = 304.5f64 * 300.0 * 300.0;
        assert_eq!(spacing, (volume / 640.0).cbrt());
        let plan = plan(&s, &BuildOptions::default()).unwrap();
        assert_eq!(plan.params.radius_mm, RADIUS_PER_SPACING * spacing);
        assert_eq!(plan.grid.cell_mm, spacing / CELLS_PER_SPACING);
        // A lattice keeps its nearest neighbour.
        let lattice = samples("");
        assert_eq!(derivation_spacing_mm(&lattice), lattice.spacing_mm());
    }
}
