//! Candidate lists: per cell, every sample that can be among the `k` nearest admissible
//! samples of some target in it (the build's module docs), found through a spatial index
//! of the samples' actual positions.

use std::sync::atomic::{AtomicU64, Ordering};

use adwi_runtime::format::{Grid, SampleRecord};
use adwi_runtime::method::{self, MethodParams};
use rayon::prelude::*;

/// Cell boxes are grown by this much (mm) when computing candidate lists.
pub const BOX_MARGIN_MM: f64 = 1e-6;
/// Slack (mm) in every distance comparison that decides a candidate list.
pub const DISTANCE_SLACK_MM: f64 = 1e-9;

/// Every cell's candidate list ([`candidate_list`]), in cell order; with `computed` (a
/// flag per cell), only the flagged cells', the others empty. `progress(n)` is called as
/// cells complete, with the number just completed (from several threads).
pub(super) fn candidate_lists(
    records: &[SampleRecord],
    params: &MethodParams,
    joint_screen: bool,
    grid: &Grid,
    computed: Option<&[bool]>,
    progress: &(dyn Fn(u64) + Sync),
) -> Vec<Vec<u32>> {
    let index = SpatialIndex::new(records, params.radius_mm);
    let done = AtomicU64::new(0);
    let cells = grid.cell_count().unwrap_or(0);
    let lists: Vec<Vec<u32>> = (0..cells)
        .into_par_iter()
        .map_init(Scratch::default, |scratch, cell| {
            let candidates = if computed.is_none_or(|c| c[cell]) {
                candidate_list(records, &index, params, joint_screen, grid, cell, scratch)
            } else {
                Vec::new()
            };
            if done.fetch_add(1, Ordering::Relaxed) % 4096 == 4095 {
                progress(4096);
            }
            candidates
        })
        .collect();
    progress(done.load(Ordering::Relaxed) % 4096);
    lists
}

/// The bytes the candidate lists of `grid` take beyond their cell records (the overflow
/// entries of lists longer than a record holds), predicted from every `stride`-th cell's
/// list and scaled: the same lists the build computes, for a fraction of its work.
pub(super) fn predicted_overflow_bytes(
    records: &[SampleRecord],
    params: &MethodParams,
    joint_screen: bool,
    grid: &Grid,
    stride: usize,
) -> u128 {
    let index = SpatialIndex::new(records, params.radius_mm);
    let inline = if records.len() <= adwi_runtime::format::v2::NARROW_SAMPLES {
        adwi_runtime::format::v2::INLINE_CANDIDATES
    } else {
        adwi_runtime::format::v2::INLINE_CANDIDATES_WIDE
    };
    let cells = grid.cell_count().unwrap_or(0);
    let stride = stride.max(1);
    let entries: u128 = (0..cells)
        .into_par_iter()
        .step_by(stride)
        .map_init(Scratch::default, |scratch, cell| {
            let len =
                candidate_list(records, &index, params, joint_screen, grid, cell, scratch).len();
            if len > inline {
                len as u128
            } else {
                0
            }
        })
        .sum();
    entries * stride as u128 * 4
}

/// Samples bucketed by actual position in cubes of edge ≥ ε, so that the samples within ε
/// of a box are found in the buckets the grown box overlaps. The buckets are one array of
/// sample indices, each bucket's a range of it (`starts`, compressed rows): a small ε gives
/// up to 257³ buckets, mostly empty, which as vectors took 24 bytes apiece (400 MB).
struct SpatialIndex {
    origin_mm: [f64; 3],
    bucket_mm: f64,
    dims: [usize; 3],
    /// Bucket `b`'s samples are `samples[starts[b]..starts[b + 1]]`, ascending.
    starts: Vec<u32>,
    samples: Vec<u32>,
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
            starts: Vec::new(),
            samples: Vec::new(),
        };
        // A counting sort by bucket: counts, their running sums, then each sample in order.
        let bucket: Vec<usize> = records
            .iter()
            .map(|r| {
                let b = index.bucket_coords(r.actual_mm);
                b[0] + dims[0] * (b[1] + dims[1] * b[2])
            })
            .collect();
        let mut starts = vec![0u32; dims[0] * dims[1] * dims[2] + 1];
        for &b in &bucket {
            starts[b + 1] += 1;
        }
        for b in 1..starts.len() {
            starts[b] += starts[b - 1];
        }
        let mut next = starts.clone();
        let mut samples = vec![0u32; records.len()];
        for (i, &b) in bucket.iter().enumerate() {
            samples[next[b] as usize] = i as u32;
            next[b] += 1;
        }
        index.starts = starts;
        index.samples = samples;
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
                // A row of buckets along x is one range of the array.
                let row = self.dims[0] * (y + self.dims[1] * z);
                let (first, last) = (self.starts[row + a[0]], self.starts[row + b[0] + 1]);
                out.extend_from_slice(&self.samples[first as usize..last as usize]);
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

/// Buffers a thread's [`candidate_list`] calls reuse from cell to cell: a table has tens
/// of thousands of cells, and each list's search, filter and sort would otherwise
/// allocate their own.
#[derive(Default)]
struct Scratch {
    /// Samples in the buckets the grown cell overlaps.
    near: Vec<u32>,
    /// (sample, nearest, farthest distance to the cell's box).
    reachable: Vec<(u32, f64, f64)>,
    /// The farthest distances of the samples admissible everywhere in the cell, sorted.
    all: Vec<f64>,
    /// The same by configuration: (configuration, farthest distance), sorted by both.
    by_config: Vec<(u8, f64)>,
    /// The list with each sample's distance to the cell's centre, to sort by.
    keyed: Vec<(f64, u32)>,
}

/// The candidate list of one cell (the build's module docs), nearest the cell's centre
/// first. `joint_screen`: whether the joint-space screen is on, so that no sample is
/// certainly admissible.
fn candidate_list(
    records: &[SampleRecord],
    index: &SpatialIndex,
    params: &MethodParams,
    joint_screen: bool,
    grid: &Grid,
    cell: usize,
    scratch: &mut Scratch,
) -> Vec<u32> {
    let Scratch {
        near,
        reachable,
        all,
        by_config,
        keyed,
    } = scratch;
    let (cell_lo, cell_hi) = grid.cell_box(grid.cell_coords(cell));
    let lo = cell_lo.map(|v| v - BOX_MARGIN_MM);
    let hi = cell_hi.map(|v| v + BOX_MARGIN_MM);
    let reach = params.radius_mm + DISTANCE_SLACK_MM;
    near.clear();
    index.near(lo.map(|v| v - reach), hi.map(|v| v + reach), near);
    reachable.clear();
    reachable.extend(near.iter().filter_map(|&i| {
        let (d_near, d_far) = box_distances(records[i as usize].actual_mm, lo, hi);
        (d_near <= reach).then_some((i, d_near, d_far))
    }));
    // Nearest to the cell's centre first (see `TableData::list_samples`).
    let centre = [0, 1, 2].map(|a| 0.5 * (cell_lo[a] + cell_hi[a]));
    let keyed_sample = |i: u32| {
        (
            method::distance_mm(records[i as usize].actual_mm, centre),
            i,
        )
    };
    keyed.clear();
    let k = params.max_neighbours as usize;
    if params.has_degree_thresholds() || joint_screen || reachable.len() <= k {
        keyed.extend(reachable.iter().map(|&(i, _, _)| keyed_sample(i)));
    } else {
        // A sample is a candidate unless k samples admissible everywhere in the cell, of
        // any configuration and of its own, are certainly nearer.
        let certain =
            |&&(_, _, far): &&(u32, f64, f64)| far <= params.radius_mm - DISTANCE_SLACK_MM;
        all.clear();
        all.extend(reachable.iter().filter(certain).map(|r| r.2));
        all.sort_by(f64::total_cmp);
        by_config.clear();
        by_config.extend(
            (reachable.iter().filter(certain)).map(|r| (records[r.0 as usize].config, r.2)),
        );
        by_config.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        for &(i, d_near, _) in reachable.iter() {
            let config = records[i as usize].config;
            let same = &by_config[by_config.partition_point(|c| c.0 < config)
                ..by_config.partition_point(|c| c.0 <= config)];
            // Samples certainly nearer than this one lie below the bound.
            let bound = d_near - DISTANCE_SLACK_MM;
            if all.partition_point(|&far| far < bound) < k
                || same.partition_point(|&(_, far)| far < bound) < k
            {
                keyed.push(keyed_sample(i));
            }
        }
    }
    keyed.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    keyed.iter().map(|&(_, i)| i).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::collections::HashMap;

    /// [`candidate_list`] written plainly, over every sample instead of the index's
    /// buckets, a map per configuration and fresh vectors per cell: the reference the
    /// index and the buffered list are held to.
    fn reference_candidate_list(
        records: &[SampleRecord],
        params: &MethodParams,
        joint_screen: bool,
        grid: &Grid,
        cell: usize,
    ) -> Vec<u32> {
        let (lo, hi) = grid.cell_box(grid.cell_coords(cell));
        let lo = lo.map(|v| v - BOX_MARGIN_MM);
        let hi = hi.map(|v| v + BOX_MARGIN_MM);
        let reach = params.radius_mm + DISTANCE_SLACK_MM;
        // Every sample, not the index's buckets: the index is held to this too.
        let near: Vec<u32> = (0..records.len() as u32).collect();

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
                let nearer = |sorted: &[f64], d: f64| {
                    sorted.partition_point(|&far| far < d - DISTANCE_SLACK_MM)
                };
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

    /// Property: the buffered list (one scratch for every cell, as a thread uses it) from
    /// the spatial index's buckets is the plain reference's over every sample, sample for sample and in order, on random sample clouds with
    /// repeated positions and several configurations, radii below and above the cell and
    /// below the buckets' smallest edge,
    /// every `k` the lists decide with, with and without degree thresholds and the joint
    /// screen.
    #[test]
    fn the_buffered_candidate_list_is_the_reference() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut filtered = 0;
        for case in 0..200 {
            let n = rng.gen_range(1..300);
            let mut records: Vec<SampleRecord> = Vec::with_capacity(n);
            for _ in 0..n {
                let actual_mm = if !records.is_empty() && rng.gen_bool(0.1) {
                    records[rng.gen_range(0..records.len())].actual_mm
                } else {
                    [0, 1, 2].map(|_| rng.gen_range(0.0..200.0))
                };
                records.push(SampleRecord {
                    actual_mm,
                    nominal_mm: actual_mm,
                    error_mm: [0.0; 3],
                    rotation_error_rad: [0.0; 3],
                    config: rng.gen_range(0..4),
                });
            }
            // Some radii below 1/256 of the cloud: the buckets are then that wide.
            let radius_mm = if case % 40 == 0 {
                rng.gen_range(0.05..0.7)
            } else {
                rng.gen_range(5.0..90.0)
            };
            let mut params = MethodParams::paper(radius_mm);
            params.max_neighbours = rng.gen_range(1..13);
            if case % 7 == 3 {
                params.lambda_min_per_mm = 0.01;
            }
            let joint_screen = case % 5 == 4;
            let grid = Grid {
                origin_mm: [0, 1, 2].map(|_| rng.gen_range(-20.0..20.0)),
                cell_mm: rng.gen_range(10.0..45.0),
                dims: [0, 1, 2].map(|_| rng.gen_range(1..9)),
            };
            let index = SpatialIndex::new(&records, params.radius_mm);
            let mut scratch = Scratch::default();
            for cell in 0..grid.cell_count().unwrap() {
                let got = candidate_list(
                    &records,
                    &index,
                    &params,
                    joint_screen,
                    &grid,
                    cell,
                    &mut scratch,
                );
                let want = reference_candidate_list(&records, &params, joint_screen, &grid, cell);
                assert_eq!(got, want, "case {case}, cell {cell}");
                let every = MethodParams {
                    max_neighbours: u32::MAX,
                    ..params
                };
                let reachable = reference_candidate_list(&records, &every, false, &grid, cell);
                filtered += usize::from(got.len() < reachable.len());
            }
        }
        // Lists the certain samples shortened: the filter was exercised.
        assert!(filtered > 1000, "{filtered} lists shortened");
    }
}
