//! Fitting a hybrid table's posture term ([`adwi_runtime::posture`]) to its samples.
//!
//! 1. **Residuals.** The table is first built without the term. Each sample's residual
//!    `r_i` is its measured position error minus what that table answers at its nominal
//!    position and joint values (the calibrated model and the served field, by the
//!    runtime's own query): the term learns only what the model and the position field
//!    leave, and adds to exactly what it was learnt against.
//! 2. **Parameters.** The supports `R`, `ℓ_q` and the floor `W0` are chosen among
//!    [`RADIUS_CANDIDATES_EPSILON`] × ε, [`LENGTH_CANDIDATES_RAD`] and
//!    [`FLOOR_CANDIDATES`] by leave-one-out on the residuals: each sample's term from the
//!    others, the lowest mean `|r_i − p_{−i}|` winning (at most [`LOO_MAX_TARGETS`]
//!    samples, evenly strided, are left out in turn, every sample serving as evidence). A
//!    sample's own residual would predict itself perfectly; leaving it out scores how the
//!    term predicts a pose it has not seen.
//! 3. **Lists.** The posture grid starts at the table grid's origin with cells of `R / 2`
//!    (larger if the grid would exceed [`MAX_POSTURE_CELLS`]) and covers the table's box:
//!    a sample is listed in the (up to 125) cells its support reaches, and a query reads
//!    about twice the samples its supports hold (cells of `R` store a quarter of the
//!    entries but make it read six times: a served query's tail latency is what counts);
//!    each cell lists, ascending, every sample within `R` of its box. A list longer than
//!    [`MAX_POSTURE_CANDIDATES`] is refused with its length (the leave-one-out's choice
//!    falls back to the best candidate whose lists fit). The record numbers the samples by
//!    posture cell ([`PostureLists::in_cell_order`]), so that a list reads a few ascending
//!    runs of positions, joints and residuals rather than indices scattered over them.
//!
//! Whether a table gets the term at all is the build's decision (`tablec build`'s
//! cross-validation): this module fits it when asked.

use adwi_runtime::format::v3::{self, MAX_POSTURE_CANDIDATES};
use adwi_runtime::format::{Grid, Tuning};
use adwi_runtime::posture::PostureParams;
use adwi_runtime::{Status, Table, Target};
use adwi_samples::SampleSet;

use crate::build::encode::{joint_terms_record, Compiled};
use crate::build::{BuildError, BuildReport};
use adwi_runtime::model::PreparedModel;

/// What a build does about the posture term.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Posture {
    /// No term: the table is version 2.
    #[default]
    Off,
    /// The term, its parameters chosen by leave-one-out (module docs).
    Fit,
    /// The term with these parameters.
    Given(PostureParams),
}

/// The spatial supports tried, as multiples of the method's radius ε.
pub const RADIUS_CANDIDATES_EPSILON: [f64; 4] = [0.5, 1.0, 1.5, 2.0];
/// The joint-space supports tried, rad.
pub const LENGTH_CANDIDATES_RAD: [f64; 6] = [0.05, 0.1, 0.2, 0.4, 0.8, 1.6];
/// The weight floors tried.
pub const FLOOR_CANDIDATES: [f64; 4] = [0.1, 0.3, 1.0, 3.0];
/// The most samples left out in turn by the leave-one-out.
pub const LOO_MAX_TARGETS: usize = 2000;
/// The most cells of a posture grid.
pub const MAX_POSTURE_CELLS: usize = 1 << 20;

/// What fitting the term found, for the build's report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PostureReport {
    /// The parameters stored.
    pub params: PostureParams,
    /// The leave-one-out mean `|r_i|`, mm: what the table without the term leaves.
    pub loo_without_mm: f64,
    /// The leave-one-out mean `|r_i − p_{−i}|` with the stored parameters, mm.
    pub loo_with_mm: f64,
    /// The posture grid's cells.
    pub cells: usize,
    /// The longest list.
    pub max_list_len: usize,
    /// Entries over every list.
    pub list_entries: usize,
}

/// Each sample's residual against `table` (built from `samples` without the term): its
/// measured error minus the table's served answer at its nominal position, configuration
/// and joint values. A sample the table does not answer (never one of its own samples,
/// whose joint values put the nominal TCP on its position) gets a zero residual, which
/// pulls the term toward zero there.
///
/// # Errors
///
/// [`BuildError::MissingJoints`] without joint values.
pub fn residuals<D: AsRef<[u8]>>(
    samples: &SampleSet,
    table: &Table<D>,
) -> Result<Vec<[f64; 3]>, BuildError> {
    let joints = samples.joints.as_ref().ok_or(BuildError::MissingJoints)?;
    Ok((0..samples.len())
        .map(|i| {
            let target = Target {
                position_mm: samples.nominal_mm[i],
                config: samples.config.as_ref().map(|c| c[i]),
                rotation_rad: None,
                tcp_mm: None,
            };
            let c = table.query_with_joints(&target, joints.row(i));
            if c.status == Status::Ok {
                [0, 1, 2].map(|a| samples.error_mm[i][a] - c.position_error_mm[a])
            } else {
                [0.0; 3]
            }
        })
        .collect())
}

/// A leave-one-out target's neighbours: sample index, distance (mm), joint distance (rad).
type Neighbours = Vec<(u32, f64, f64)>;

/// The parameters `posture` asks for, or that the leave-one-out chooses among those whose
/// lists fit, with the leave-one-out's figures and the lists (module docs).
///
/// # Errors
///
/// [`BuildError::PostureTooDense`] when no candidate's lists fit (given parameters: when
/// theirs do not).
pub fn fit(
    samples: &SampleSet,
    residuals_mm: &[[f64; 3]],
    grid: &Grid,
    radius_mm: f64,
    posture: Posture,
) -> Result<(PostureReport, v3::PostureRecord), BuildError> {
    let joints = samples.joints.as_ref().ok_or(BuildError::MissingJoints)?;
    let n = samples.len();
    let targets: Vec<usize> = if n > LOO_MAX_TARGETS {
        let stride = n as f64 / LOO_MAX_TARGETS as f64;
        (0..LOO_MAX_TARGETS)
            .map(|i| (i as f64 * stride) as usize)
            .collect()
    } else {
        (0..n).collect()
    };
    let candidates: Vec<PostureParams> = match posture {
        Posture::Given(p) => vec![p],
        _ => RADIUS_CANDIDATES_EPSILON
            .iter()
            .flat_map(|&r| {
                LENGTH_CANDIDATES_RAD.iter().flat_map(move |&l| {
                    FLOOR_CANDIDATES.iter().map(move |&w| PostureParams {
                        radius_mm: r * radius_mm,
                        length_rad: l,
                        floor: w,
                    })
                })
            })
            .collect(),
    };
    let reach_mm = candidates.iter().map(|p| p.radius_mm).fold(0.0, f64::max);
    let neighbours = neighbours(samples, joints, &targets, reach_mm);
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let loo_without_mm =
        targets.iter().map(|&t| norm(residuals_mm[t])).sum::<f64>() / targets.len().max(1) as f64;
    let mut scored: Vec<(f64, usize)> = candidates
        .iter()
        .enumerate()
        .map(|(c, params)| {
            let total: f64 = targets
                .iter()
                .zip(&neighbours)
                .map(|(&t, near)| {
                    let mut weight_sum = 0.0;
                    let mut weighted = [0.0; 3];
                    for &(j, d_mm, dq_rad) in near {
                        let w = params.weight_at(d_mm, dq_rad);
                        if w > 0.0 {
                            weight_sum += w;
                            for (s, r) in weighted.iter_mut().zip(residuals_mm[j as usize]) {
                                *s += w * r;
                            }
                        }
                    }
                    let p = params.term(weight_sum, weighted);
                    norm([0, 1, 2].map(|a| residuals_mm[t][a] - p[a]))
                })
                .sum();
            (total / targets.len().max(1) as f64, c)
        })
        .collect();
    // The best first; ties keep the order tried (smaller supports first).
    scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut longest = 0;
    for &(loo_with_mm, c) in &scored {
        let params = candidates[c];
        let mut lists = lists(&params, grid, &samples.nominal_mm)?;
        let max_list_len = lists.longest();
        if max_list_len > MAX_POSTURE_CANDIDATES {
            longest = longest.max(max_list_len);
            continue;
        }
        let report = PostureReport {
            params,
            loo_without_mm,
            loo_with_mm,
            cells: lists.offsets.len() - 1,
            max_list_len,
            list_entries: lists.entries.len(),
        };
        let order = lists.in_cell_order(grid, &samples.nominal_mm);
        let record = v3::PostureRecord {
            radius_mm: params.radius_mm,
            length_rad: params.length_rad,
            floor: params.floor,
            cell_mm: lists.cell_mm,
            dims: lists.dims,
            cell_offsets: lists.offsets,
            cell_samples: lists.entries,
            positions_mm: order.iter().map(|&i| samples.nominal_mm[i]).collect(),
            joints_rad: order.iter().flat_map(|&i| joints.row(i)).copied().collect(),
            residuals_mm: order.iter().map(|&i| residuals_mm[i]).collect(),
        };
        return Ok((report, record));
    }
    Err(BuildError::PostureTooDense {
        longest,
        max: MAX_POSTURE_CANDIDATES,
    })
}

/// For each target, every other sample within `reach_mm`, ascending, with its distance
/// and joint distance: a hash of cubes of `reach_mm`, the 27 around each target searched.
fn neighbours(
    samples: &SampleSet,
    joints: &adwi_samples::Joints,
    targets: &[usize],
    reach_mm: f64,
) -> Vec<Neighbours> {
    let key = |p: [f64; 3]| p.map(|v| (v / reach_mm).floor() as i64);
    let mut buckets: rustc_hash::FxHashMap<[i64; 3], Vec<u32>> = Default::default();
    for (i, &p) in samples.nominal_mm.iter().enumerate() {
        buckets.entry(key(p)).or_default().push(i as u32);
    }
    targets
        .iter()
        .map(|&t| {
            let x = samples.nominal_mm[t];
            let k = key(x);
            let mut near: Neighbours = Vec::new();
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(bucket) = buckets.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else {
                            continue;
                        };
                        for &j in bucket {
                            let d_mm = adwi_runtime::method::distance_mm(
                                x,
                                samples.nominal_mm[j as usize],
                            );
                            if j as usize == t || d_mm >= reach_mm {
                                continue;
                            }
                            let dq2: f64 = (joints.row(t).iter().zip(joints.row(j as usize)))
                                .map(|(a, b)| (a - b) * (a - b))
                                .sum();
                            near.push((j, d_mm, dq2.sqrt()));
                        }
                    }
                }
            }
            near.sort_by_key(|n| n.0);
            near
        })
        .collect()
}

/// A posture grid's lists ([`lists`]).
pub struct PostureLists {
    /// The grid's cell edge, mm.
    pub cell_mm: f64,
    /// Its cells along x, y, z.
    pub dims: [u32; 3],
    /// Cell `c`'s list is `entries[offsets[c]..offsets[c + 1]]`.
    pub offsets: Vec<u32>,
    /// The lists, each ascending.
    pub entries: Vec<u32>,
}

impl PostureLists {
    /// Numbers the samples (at `positions_mm`, over the table's `grid`) by ascending
    /// posture cell, x fastest, then by their own order, and the lists with them, each
    /// list still ascending: the record's sample `k` is `positions_mm[order[k]]` for the
    /// `order` returned. A list then reads its samples' positions, joints and residuals
    /// as a few ascending runs of memory (one per row of cells its support covers),
    /// instead of indices scattered over the whole record. A sample outside the posture
    /// grid (the table's box given smaller than the samples') comes last.
    pub fn in_cell_order(&mut self, grid: &Grid, positions_mm: &[[f64; 3]]) -> Vec<usize> {
        let posture_grid = Grid {
            origin_mm: grid.origin_mm,
            cell_mm: self.cell_mm,
            dims: self.dims,
        };
        let mut order: Vec<usize> = (0..positions_mm.len()).collect();
        order.sort_by_key(|&i| {
            (
                posture_grid.cell_of(positions_mm[i]).unwrap_or(usize::MAX),
                i,
            )
        });
        let mut rank = vec![0u32; order.len()];
        for (k, &i) in order.iter().enumerate() {
            rank[i] = k as u32;
        }
        for w in self.offsets.windows(2) {
            let list = &mut self.entries[w[0] as usize..w[1] as usize];
            for e in list.iter_mut() {
                *e = rank[*e as usize];
            }
            list.sort_unstable();
        }
        order
    }

    /// The longest list.
    pub fn longest(&self) -> usize {
        self.offsets
            .windows(2)
            .map(|w| (w[1] - w[0]) as usize)
            .max()
            .unwrap_or(0)
    }
}

/// The posture grid over the table's `grid` for `params` and each of its cells' list:
/// every sample whose position is within `R` of the cell's box (with a slack far above
/// rounding, so that a target rounded into a neighbouring cell still finds every sample
/// that reaches it).
///
/// # Errors
///
/// [`BuildError::PostureTooDense`] when the lists would exceed the format's `u32` range.
pub fn lists(
    params: &PostureParams,
    grid: &Grid,
    positions_mm: &[[f64; 3]],
) -> Result<PostureLists, BuildError> {
    let extent_mm = [0, 1, 2].map(|a| grid.max_mm()[a] - grid.origin_mm[a]);
    let dims_for = |cell_mm: f64| extent_mm.map(|e| ((e / cell_mm).ceil() as u64).max(1));
    let mut cell_mm = params.radius_mm / 2.0;
    while dims_for(cell_mm).iter().product::<u64>() > MAX_POSTURE_CELLS as u64 {
        cell_mm *= 1.25;
    }
    let mut posture_grid = Grid {
        origin_mm: grid.origin_mm,
        cell_mm,
        dims: dims_for(cell_mm).map(|d| d as u32),
    };
    // Rounding of `origin + dims · cell` must not leave the table's maximum face outside.
    let table_max = grid.max_mm();
    for (axis, &max_mm) in table_max.iter().enumerate() {
        while posture_grid.max_mm()[axis] < max_mm {
            posture_grid.dims[axis] += 1;
        }
    }
    let [nx, ny, nz] = posture_grid.dims.map(|v| v as usize);
    let reach_mm = params.radius_mm * (1.0 + 1e-9) + 1e-6;
    let mut per_cell: Vec<Vec<u32>> = vec![Vec::new(); nx * ny * nz];
    for (i, &x) in positions_mm.iter().enumerate() {
        let range = |axis: usize, n: usize| {
            let lo = ((x[axis] - reach_mm - grid.origin_mm[axis]) / cell_mm).floor();
            let hi = ((x[axis] + reach_mm - grid.origin_mm[axis]) / cell_mm).floor();
            let clamp = |v: f64| v.clamp(0.0, (n - 1) as f64) as usize;
            clamp(lo)..=clamp(hi)
        };
        for iz in range(2, nz) {
            for iy in range(1, ny) {
                for ix in range(0, nx) {
                    let (lo, hi) = posture_grid.cell_box([ix, iy, iz]);
                    let outside_mm2: f64 = (0..3)
                        .map(|a| (lo[a] - x[a]).max(x[a] - hi[a]).max(0.0).powi(2))
                        .sum();
                    if outside_mm2 <= reach_mm * reach_mm {
                        per_cell[posture_grid.linear_index([ix, iy, iz])].push(i as u32);
                    }
                }
            }
        }
    }
    let mut offsets = Vec::with_capacity(per_cell.len() + 1);
    let mut entries = Vec::new();
    offsets.push(0u32);
    for list in per_cell {
        entries.extend_from_slice(&list);
        let end = u32::try_from(entries.len()).map_err(|_| BuildError::PostureTooDense {
            longest: list.len(),
            max: MAX_POSTURE_CANDIDATES,
        })?;
        offsets.push(end);
    }
    Ok(PostureLists {
        cell_mm,
        dims: posture_grid.dims,
        offsets,
        entries,
    })
}

/// `table` (a hybrid table of `samples` compiled without the term, whose bytes answer the
/// residuals of step 1) with the posture term fitted as `posture` asks (never
/// [`Posture::Off`]), its header's tuning as `tuning` says: the bytes of the table with the
/// term (version 3, or 5 with the `model`'s joint-space terms) and its build report, the
/// fit's report in it. The
/// payload is extended from the values the compiler holds, not decoded from its bytes.
///
/// # Errors
///
/// [`BuildError::MissingJoints`], [`BuildError::PostureTooDense`], an encoding failure,
/// and [`BuildError::Unopenable`] for a table the runtime would refuse (a bug).
pub(crate) fn add_term(
    table: Compiled,
    samples: &SampleSet,
    model: &PreparedModel,
    posture: Posture,
    tuning: Option<Tuning>,
) -> Result<(Vec<u8>, BuildReport), BuildError> {
    let residuals_mm = residuals(
        samples,
        &Table::from_vec(&table.bytes).map_err(BuildError::Unopenable)?,
    )?;
    let (fitted, posture) = fit(
        samples,
        &residuals_mm,
        &table.header.grid,
        table.header.method.radius_mm,
        posture,
    )?;
    let header = adwi_runtime::format::Header {
        tuning,
        ..table.header
    };
    let base = table.data;
    // The model's joint record kept: a version-6 table with the posture term.
    let data = adwi_runtime::format::v5::TableData {
        base,
        posture,
        joint_terms: joint_terms_record(model, table.joint_count),
    };
    let bytes = adwi_runtime::format::encode_v6(header, &data, true)
        .map_err(|e| BuildError::Encode(e.to_string()))?;
    if table.opened {
        crate::build::encode::check_opens(&bytes)?;
    }
    let report = BuildReport {
        table_bytes: bytes.len(),
        posture: Some(fitted),
        ..table.report
    };
    Ok((bytes, report))
}
