//! Measuring query latency, and the alternatives a table is measured against.
//!
//! Used by `tablec bench`, by the criterion benchmark `benches/latency.rs` and by the
//! latency guard test, so that all three measure the same way:
//!
//! - **Per-query timing.** Each call is timed on its own with [`std::time::Instant`], and
//!   the cost of an empty timed region (the median of many, calibrated once by
//!   [`Timer::calibrate`]) is subtracted. Per-query times give the tail (p99, p99.9, max)
//!   that a batch mean hides; the mean of the corrected times is cross-checked against a
//!   batch timing.
//! - **Workloads.** Uniformly random targets in the table's grid ([`random_targets`]), and
//!   a controller-like path whose consecutive targets are 1 mm apart ([`trajectory`]), which
//!   keeps the same cells (and cache lines) hot as a real motion does.
//! - **Alternatives.** [`KdTreeMethod`] is what an integrator would write without a table:
//!   a k-d tree (`kiddo`) of the samples built at start-up, every sample within ε found per
//!   query, the nearest admissible `k` selected and weighted by the same
//!   [`adwi_runtime::method`] functions. The brute-force reference is
//!   [`adwi_compile::reference::predict`].

use std::time::{Duration, Instant};

use adwi_compile::reference;
use adwi_runtime::format::{v1, v2, Grid, Header, SampleRecord, HEADER_LEN};
use adwi_runtime::method::{self, Estimate, MethodParams};
use adwi_runtime::{AlignedBytes, Payload, Status, Table, Target};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Percentiles of per-query times, nanoseconds.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Number of timed queries.
    pub count: usize,
    /// Median.
    pub p50_ns: f64,
    /// 99th percentile.
    pub p99_ns: f64,
    /// 99.9th percentile.
    pub p999_ns: f64,
    /// Slowest query.
    pub max_ns: f64,
    /// Mean of the per-query times.
    pub mean_ns: f64,
}

impl Summary {
    /// Summarises per-query times (ns); `None` for no times.
    pub fn of(mut times_ns: Vec<f64>) -> Option<Summary> {
        if times_ns.is_empty() {
            return None;
        }
        times_ns.sort_by(f64::total_cmp);
        // Nearest-rank percentile: the smallest time at or above fraction `f` of the queries.
        let rank = |f: f64| {
            let i = (f * times_ns.len() as f64).ceil() as usize;
            times_ns[i.clamp(1, times_ns.len()) - 1]
        };
        Some(Summary {
            count: times_ns.len(),
            p50_ns: rank(0.50),
            p99_ns: rank(0.99),
            p999_ns: rank(0.999),
            max_ns: times_ns[times_ns.len() - 1],
            mean_ns: times_ns.iter().sum::<f64>() / times_ns.len() as f64,
        })
    }
}

/// Times single calls, with the cost of reading the clock subtracted.
#[derive(Clone, Copy, Debug)]
pub struct Timer {
    /// The median time of an empty timed region, ns.
    pub overhead_ns: f64,
}

impl Timer {
    /// Measures the clock's overhead: the median of 100,000 empty timed regions.
    pub fn calibrate() -> Timer {
        let mut empty: Vec<f64> = (0..100_000)
            .map(|_| {
                let start = Instant::now();
                std::hint::black_box(());
                start.elapsed().as_nanos() as f64
            })
            .collect();
        empty.sort_by(f64::total_cmp);
        Timer {
            overhead_ns: empty[empty.len() / 2],
        }
    }

    /// Calls `query` once per input after one untimed warm-up pass over up to 1,000 of
    /// them, timing each call; returns the per-call times (ns, overhead subtracted,
    /// floored at 0).
    pub fn time_each<I, R>(&self, inputs: &[I], mut query: impl FnMut(&I) -> R) -> Vec<f64> {
        for input in inputs.iter().take(1_000) {
            std::hint::black_box(query(std::hint::black_box(input)));
        }
        inputs
            .iter()
            .map(|input| {
                let input = std::hint::black_box(input);
                let start = Instant::now();
                let answer = query(input);
                let elapsed = start.elapsed();
                std::hint::black_box(answer);
                (elapsed.as_nanos() as f64 - self.overhead_ns).max(0.0)
            })
            .collect()
    }

    /// The mean time per call over one batch, without per-call clock reads: a check on
    /// [`Timer::time_each`]'s overhead correction.
    pub fn batch_mean_ns<I, R>(inputs: &[I], mut query: impl FnMut(&I) -> R) -> f64 {
        let start = Instant::now();
        for input in inputs {
            std::hint::black_box(query(std::hint::black_box(input)));
        }
        start.elapsed().as_nanos() as f64 / inputs.len().max(1) as f64
    }
}

/// `count` targets uniformly distributed in `grid`'s box.
pub fn random_targets(grid: &Grid, count: usize, seed: u64) -> Vec<Target> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let max = grid.max_mm();
    (0..count)
        .map(|_| Target::at([0, 1, 2].map(|a| rng.gen_range(grid.origin_mm[a]..max[a]))))
        .collect()
}

/// A path of `count` targets `step_mm` apart through `grid`'s box: straight lines in
/// random directions, reflected at the box's faces and turning every 200 steps, as a
/// controller's interpolated motion would visit them.
pub fn trajectory(grid: &Grid, count: usize, step_mm: f64, seed: u64) -> Vec<Target> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let lo = grid.origin_mm;
    let hi = grid.max_mm();
    let mut p = [0, 1, 2].map(|a| rng.gen_range(lo[a]..hi[a]));
    let mut direction = [0.0; 3];
    let mut out = Vec::with_capacity(count);
    for i in 0..count {
        if i % 200 == 0 {
            direction = random_unit(&mut rng);
        }
        for a in 0..3 {
            p[a] += step_mm * direction[a];
            if p[a] < lo[a] || p[a] > hi[a] {
                direction[a] = -direction[a];
                p[a] = p[a].clamp(lo[a], hi[a]);
            }
        }
        out.push(Target::at(p));
    }
    out
}

pub(crate) fn random_unit(rng: &mut ChaCha8Rng) -> [f64; 3] {
    loop {
        let v = [0; 3].map(|_| rng.gen_range(-1.0..1.0));
        let n = method::distance_mm(v, [0.0; 3]);
        if n > 1e-3 && n <= 1.0 {
            return v.map(|x| x / n);
        }
    }
}

/// The samples of a table, as the records it was built from (nominal positions as
/// `actual − error`: a version-2 table stores what queries read, not the nominal).
pub fn records_of<D: AsRef<[u8]>>(table: &Table<D>) -> Vec<SampleRecord> {
    let native = |v: &rkyv::Archived<[f64; 3]>| v.map(|x| x.to_native());
    match table.payload() {
        None => Vec::new(),
        Some(Payload::V1(data)) => data
            .samples
            .iter()
            .map(|s| SampleRecord {
                actual_mm: native(&s.actual_mm),
                nominal_mm: native(&s.nominal_mm),
                error_mm: native(&s.error_mm),
                rotation_error_rad: native(&s.rotation_error_rad),
                config: s.config,
            })
            .collect(),
        Some(Payload::V2(data)) => (0..data.samples.len())
            .map(|i| {
                let actual_mm = native(&data.samples[i].actual_mm);
                let error_mm = native(&data.errors_mm[i]);
                SampleRecord {
                    actual_mm,
                    nominal_mm: [0, 1, 2].map(|a| actual_mm[a] - error_mm[a]),
                    error_mm,
                    rotation_error_rad: data.orientation_errors_rad.get(i).map_or([0.0; 3], native),
                    config: data
                        .configs
                        .get(i)
                        .copied()
                        .unwrap_or(method::CONFIG_UNKNOWN),
                }
            })
            .collect(),
    }
}

/// The method without a table: a k-d tree of the samples' actual positions, queried for
/// every sample within ε, then the same selection and weighting as the runtime.
pub struct KdTreeMethod {
    tree: ImmutableKdTree<f64, 3>,
    records: Vec<SampleRecord>,
    params: MethodParams,
    orientation: bool,
}

impl KdTreeMethod {
    /// Builds the tree: what an integrator's start-up would do.
    pub fn new(records: Vec<SampleRecord>, params: MethodParams) -> KdTreeMethod {
        let points: Vec<[f64; 3]> = records.iter().map(|r| r.actual_mm).collect();
        let orientation = records.iter().any(|r| r.rotation_error_rad != [0.0; 3]);
        KdTreeMethod {
            tree: ImmutableKdTree::new_from_slice(&points),
            records,
            params,
            orientation,
        }
    }

    /// The prediction at `target`, or `None` without admissible neighbours. Allocates the
    /// k-d tree's result vector per query, as its API does.
    pub fn predict(&self, target: &Target) -> Option<Estimate> {
        let p = target.position_mm;
        if !p.iter().all(|v| v.is_finite()) {
            return None;
        }
        // Squared radius grown by a relative 1e-12 so that rounding in the tree's squared
        // distances never drops a sample the method's own distance admits; `select` then
        // applies the exact radius.
        let r2 = self.params.radius_mm * self.params.radius_mm * (1.0 + 1e-12);
        let within = self.tree.within_unsorted::<SquaredEuclidean>(&p, r2);
        let records = &self.records;
        let selection = method::select(
            &self.params,
            p,
            target.config,
            within.iter().map(|n| n.item as u32),
            |i| {
                let r = records.get(i as usize)?;
                Some((r.actual_mm, r.config))
            },
        );
        method::estimate(&self.params, p, &selection, self.orientation, |i| {
            let r = &records[i as usize];
            (
                r.actual_mm,
                method::norm_mm(r.actual_mm),
                r.measured_error(),
            )
        })
    }
}

/// A contender of [`bench_queries`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Contender {
    /// The table's served tier: the continuous field (8 nodes, trilinear).
    Trilinear,
    /// The table's exact tier: the method over the cell's candidate list.
    Exact,
    /// A k-d tree of the samples with the same selection and weights ([`KdTreeMethod`]).
    KdTree,
    /// The brute-force reference over every sample.
    Brute,
}

impl Contender {
    /// Every contender, in report order.
    pub const ALL: [Contender; 4] = [
        Contender::Trilinear,
        Contender::Exact,
        Contender::KdTree,
        Contender::Brute,
    ];

    /// The name used in reports and in `tablec bench --json`.
    pub fn name(self) -> &'static str {
        match self {
            Contender::Trilinear => "trilinear",
            Contender::Exact => "exact",
            Contender::KdTree => "kdtree",
            Contender::Brute => "brute",
        }
    }
}

/// One workload's measurements.
#[derive(Clone, Debug)]
pub struct WorkloadResult {
    /// `random` or `trajectory`.
    pub name: &'static str,
    /// Targets timed (the brute force: at most the reference count).
    pub targets: usize,
    /// Targets the served tier answered, and the exact tier.
    pub answered: (usize, usize),
    /// Per contender: the per-query summary and the batch mean (ns).
    pub timings: Vec<(Contender, Summary, f64)>,
    /// Of the targets compared, how many the k-d tree and the brute force answered
    /// exactly as the exact tier (same status, same bits), and out of how many.
    pub agreement: [(usize, usize); 2],
}

/// What [`bench_queries`] times.
#[derive(Clone, Copy, Debug)]
pub struct BenchOptions {
    /// Timed queries per workload and contender.
    pub queries: usize,
    /// Timed queries per workload for the brute force (slow: every sample per query).
    pub reference_queries: usize,
    /// Seed of the workloads.
    pub seed: u64,
}

/// Times every contender on the two workloads: targets uniform in the grid (`random`), and
/// a path of targets 1 mm apart (`trajectory`). A hybrid table's targets come with joint
/// values ([`hybrid_workload`]: random poses; the path moves every joint by at most 1 mm at
/// the tool), and every contender adds the model part, as the table does. `None` when the
/// table's bytes changed or a hybrid table yields no pose in its grid.
pub fn bench_queries<D: AsRef<[u8]>>(
    table: &Table<D>,
    timer: &Timer,
    options: &BenchOptions,
) -> Option<Vec<WorkloadResult>> {
    let records = records_of(table);
    let params = *table.method();
    let kd = KdTreeMethod::new(records.clone(), params);
    let model = table.model().copied();
    // Where no sample is admissible a hybrid table's exact tier answers the model alone,
    // and so does every contender: each then does the work the table does, the model (with
    // its orientation error where the samples measured orientation, as the table serves
    // it) added to the estimate.
    let rotation = table.has_orientation();
    let with_model = |estimate: Option<Estimate>, q: Option<&[f64]>| -> Option<[[f64; 3]; 2]> {
        match (&model, q) {
            (Some(m), Some(q)) => {
                let at = m.evaluate(q, rotation)?;
                let (e, r) = estimate.map_or(([0.0; 3], [0.0; 3]), |e| {
                    (e.position_error_mm, e.orientation_error_rad)
                });
                Some([
                    [0, 1, 2].map(|a| e[a] + at.position_mm[a]),
                    [0, 1, 2].map(|a| r[a] + at.rotation_rad[a]),
                ])
            }
            _ => estimate.map(|e| [e.position_error_mm, e.orientation_error_rad]),
        }
    };
    let brute = |t: &Target| {
        reference::predict(&records, &params, t).map(|p| Estimate {
            position_error_mm: p.position_error_mm,
            orientation_error_rad: p.orientation_error_rad,
            neighbours: p.neighbours.len() as u32,
        })
    };
    /// A target and, for a hybrid table, its joint angles.
    type Query = (Target, Option<Vec<f64>>);
    let grid = *table.grid();
    let workloads: Vec<(&'static str, Vec<Query>)> = if table.is_hybrid() {
        let poses = hybrid_workload(table, options.queries, options.seed)?;
        let path = joint_path(table, &poses, options.queries);
        let wrap = |v: Vec<(Target, Vec<f64>)>| v.into_iter().map(|(t, q)| (t, Some(q))).collect();
        vec![("random", wrap(poses)), ("trajectory", wrap(path))]
    } else {
        let none = |v: Vec<Target>| v.into_iter().map(|t| (t, None)).collect();
        vec![
            (
                "random",
                none(random_targets(&grid, options.queries, options.seed)),
            ),
            (
                "trajectory",
                none(trajectory(&grid, options.queries, 1.0, options.seed)),
            ),
        ]
    };
    let served = |(t, q): &(Target, Option<Vec<f64>>)| match q {
        Some(q) => table.query_with_joints(t, q),
        None => table.query_target(t),
    };
    let exact = |(t, q): &(Target, Option<Vec<f64>>)| match q {
        Some(q) => table.exact().query_with_joints(t, q),
        None => table.exact().query_target(t),
    };
    let mut out = Vec::new();
    for (name, inputs) in workloads {
        let few = &inputs[..options.reference_queries.min(inputs.len())];
        let kd_query =
            |(t, q): &(Target, Option<Vec<f64>>)| with_model(kd.predict(t), q.as_deref());
        let brute_query = |(t, q): &(Target, Option<Vec<f64>>)| with_model(brute(t), q.as_deref());
        let mut timings = Vec::new();
        for contender in Contender::ALL {
            let (times, batch) = match contender {
                Contender::Trilinear => (
                    timer.time_each(&inputs, served),
                    Timer::batch_mean_ns(&inputs, served),
                ),
                Contender::Exact => (
                    timer.time_each(&inputs, exact),
                    Timer::batch_mean_ns(&inputs, exact),
                ),
                Contender::KdTree => (
                    timer.time_each(&inputs, kd_query),
                    Timer::batch_mean_ns(&inputs, kd_query),
                ),
                Contender::Brute => (
                    timer.time_each(few, brute_query),
                    Timer::batch_mean_ns(few, brute_query),
                ),
            };
            timings.push((contender, Summary::of(times)?, batch));
        }
        let same = |input: &(Target, Option<Vec<f64>>), other: Option<[[f64; 3]; 2]>| {
            let c = exact(input);
            match other {
                Some([p, r]) => {
                    c.status == Status::Ok
                        && c.position_error_mm == p
                        && c.orientation_error_rad == r
                }
                None => c.status != Status::Ok,
            }
        };
        let kd_same = inputs.iter().filter(|i| same(i, kd_query(i))).count();
        let brute_same = few.iter().filter(|i| same(i, brute_query(i))).count();
        out.push(WorkloadResult {
            name,
            targets: inputs.len(),
            answered: (
                inputs
                    .iter()
                    .filter(|i| served(i).status == Status::Ok)
                    .count(),
                inputs
                    .iter()
                    .filter(|i| exact(i).status == Status::Ok)
                    .count(),
            ),
            timings,
            agreement: [(kd_same, inputs.len()), (brute_same, few.len())],
        });
    }
    Some(out)
}

/// A hybrid table's trajectory: from each random pose, small joint steps (each joint by
/// up to 1 mm of tool motion, assuming a 1 m lever) for 200 steps, then the next pose.
fn joint_path<D: AsRef<[u8]>>(
    table: &Table<D>,
    poses: &[(Target, Vec<f64>)],
    count: usize,
) -> Vec<(Target, Vec<f64>)> {
    let Some(model) = table.model() else {
        return Vec::new();
    };
    let nominal = model.nominal();
    let mut rng = ChaCha8Rng::seed_from_u64(poses.len() as u64);
    let mut out = Vec::with_capacity(count);
    let mut q = poses.first().map(|p| p.1.clone()).unwrap_or_default();
    let mut direction: Vec<f64> = Vec::new();
    for i in 0..count {
        if i % 200 == 0 {
            q = poses[(i / 200) % poses.len()].1.clone();
            direction = (0..q.len()).map(|_| rng.gen_range(-1e-3..1e-3)).collect();
        }
        for (v, d) in q.iter_mut().zip(&direction) {
            *v += d;
        }
        if let Some(pose) = nominal.tcp_pose(&q) {
            out.push((Target::at(pose.translation_mm), q.clone()));
        }
    }
    out
}

/// Times `f` `repeats` times; returns the per-run durations, sorted.
pub fn time_runs<R>(repeats: usize, mut f: impl FnMut() -> R) -> Vec<Duration> {
    let mut runs: Vec<Duration> = (0..repeats.max(1))
        .map(|_| {
            let start = Instant::now();
            std::hint::black_box(f());
            start.elapsed()
        })
        .collect();
    runs.sort();
    runs
}

/// Reads the file and deserialises its payload into an owned copy, as a format without
/// zero-copy access would have to; returns the sample count.
pub fn deserialise_owned(path: &std::path::Path) -> Option<usize> {
    let bytes = std::fs::read(path).ok()?;
    let aligned = AlignedBytes::copy_from(&bytes).ok()?;
    let payload = aligned.get(HEADER_LEN..)?;
    match Header::from_bytes(&bytes).ok()?.version {
        1 => rkyv::from_bytes::<v1::TableData, rkyv::rancor::Error>(payload)
            .ok()
            .map(|d| d.samples.len()),
        _ => rkyv::from_bytes::<v2::TableData, rkyv::rancor::Error>(payload)
            .ok()
            .map(|d| d.samples.len()),
    }
}

/// A hybrid table answers only with the joint values the controller will use, which only
/// the controller's inverse kinematics knows for an arbitrary target: the workload is
/// random joint values, kept where the nominal tool position falls inside the table's
/// grid, queried there with those values (model evaluation plus the residual field). Each
/// joint is drawn within the angles the samples span when the table records them
/// (format version 6: where its residual is served, as a controller commands the arm where
/// it was measured), else in ±π (prismatic joints ±π mm). `None` for a table without a
/// model, or when no pose of a million tries falls in the grid.
pub fn hybrid_workload<D: AsRef<[u8]>>(
    table: &Table<D>,
    queries: usize,
    seed: u64,
) -> Option<Vec<(Target, Vec<f64>)>> {
    let model = table.model()?;
    let nominal = model.nominal();
    let n = nominal.joint_count();
    let pi = std::f64::consts::PI;
    let ranges: Vec<[f64; 2]> = (0..n)
        .map(|j| match model.joint_terms().range_rad[j] {
            [lo, hi] if model.bounds_residual() && lo.is_finite() && hi.is_finite() => [lo, hi],
            _ => [-pi, pi],
        })
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(queries);
    for _ in 0..1_000_000 {
        if out.len() == queries.max(1) {
            break;
        }
        let q: Vec<f64> = ranges
            .iter()
            .map(|&[lo, hi]| if lo < hi { rng.gen_range(lo..hi) } else { lo })
            .collect();
        let p = nominal.tcp_pose(&q)?.translation_mm;
        if table.grid().cell_of(p).is_some() {
            out.push((Target::at(p), q));
        }
    }
    (!out.is_empty()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every contender does the work the table does: on a hybrid table the k-d tree and the
    /// brute force add the model (its orientation error where the samples measured one, as
    /// the table serves it), and so answer exactly as the exact tier, position and
    /// orientation.
    #[test]
    fn on_a_hybrid_table_every_contender_answers_as_the_exact_tier() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../tables/compat/v4/ur5_hybrid.tbl"
        );
        let table = Table::from_vec(std::fs::read(path).expect("the shipped table"))
            .expect("a valid table");
        assert!(table.is_hybrid());
        let options = BenchOptions {
            queries: 300,
            reference_queries: 20,
            seed: 3,
        };
        let timer = Timer { overhead_ns: 0.0 };
        let results = bench_queries(&table, &timer, &options).expect("poses in the grid");
        for w in &results {
            assert!(w.answered.1 > 0, "{}: nothing answered", w.name);
            for (agreed, of) in w.agreement {
                assert!(of > 0 && agreed == of, "{}: {agreed} of {of}", w.name);
            }
        }
    }

    #[test]
    fn percentiles_are_nearest_rank() {
        let s = Summary::of((1..=1000).map(f64::from).collect()).unwrap();
        assert_eq!(s.count, 1000);
        assert_eq!(s.p50_ns, 500.0);
        assert_eq!(s.p99_ns, 990.0);
        assert_eq!(s.p999_ns, 999.0);
        assert_eq!(s.max_ns, 1000.0);
        assert_eq!(s.mean_ns, 500.5);
        assert!(Summary::of(Vec::new()).is_none());
    }

    #[test]
    fn trajectory_steps_are_one_millimetre_and_stay_in_the_grid() {
        let grid = Grid {
            origin_mm: [0.0; 3],
            cell_mm: 10.0,
            dims: [5, 5, 5],
        };
        let path = trajectory(&grid, 5_000, 1.0, 3);
        for w in path.windows(2) {
            let d = method::distance_mm(w[0].position_mm, w[1].position_mm);
            assert!(d <= 1.0 + 1e-9, "step {d}");
        }
        assert!(path.iter().all(|t| grid.cell_of(t.position_mm).is_some()));
    }
}
