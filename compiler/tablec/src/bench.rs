//! `tablec bench`: query and open latency of a table, next to the alternatives.

use std::path::PathBuf;
use std::time::Duration;

use adwi_compile::reference;
use adwi_eval::latency::{self, KdTreeMethod, Summary, Timer};
use adwi_runtime::{Status, Table};
use anyhow::Context;

#[derive(clap::Args)]
pub struct Args {
    /// The table.
    table: PathBuf,
    /// Timed queries per workload for the table and the k-d tree.
    #[arg(long, default_value_t = 100_000)]
    queries: usize,
    /// Timed queries per workload for the brute-force reference (slow: every sample per
    /// query).
    #[arg(long, default_value_t = 2_000)]
    reference_queries: usize,
    /// Timed repetitions of each way of opening the table.
    #[arg(long, default_value_t = 20)]
    open_repeats: usize,
    /// Seed of the random targets and the trajectory.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

const METHOD: &str = "\
Method: single thread; each query timed on its own with std::time::Instant, minus the
median cost of an empty timed region; one untimed warm-up pass first. Percentiles are
nearest-rank over all timed queries. 'batch' is the mean per query of one untimed-per-call
batch, a check on the overhead correction. Workloads: targets uniform in the table's grid,
and a trajectory of targets 1 mm apart (straight segments of 200 mm, reflected at the
grid's faces). Contenders: the table; (a) the brute-force reference over every sample;
(b) a k-d tree (kiddo, built at start-up) finding every sample within epsilon, then the
same selection and weights (adwi_runtime::method). Open: (c) memory map + full validation
vs. reading the file and deserialising an owned copy (rkyv validation, no semantic checks).";

pub fn run(args: Args) -> anyhow::Result<()> {
    let table = crate::open_table(&args.table)?;
    let records = latency::records_of(&table);
    let params = *table.method();
    let grid = *table.grid();
    println!("{METHOD}\n");
    println!(
        "table {}: {} samples, {} cells of {} mm, k = {}, epsilon = {} mm",
        args.table.display(),
        records.len(),
        grid.cell_count().unwrap_or(0),
        grid.cell_mm,
        params.max_neighbours,
        params.radius_mm
    );
    let timer = Timer::calibrate();
    println!(
        "clock overhead {:.1} ns per timed region\n",
        timer.overhead_ns
    );

    if table.is_hybrid() {
        return bench_hybrid(&table, &timer, args.queries, args.seed);
    }
    let kd = KdTreeMethod::new(records.clone(), params);
    let workloads = [
        (
            "random in grid",
            latency::random_targets(&grid, args.queries, args.seed),
        ),
        (
            "trajectory 1 mm",
            latency::trajectory(&grid, args.queries, 1.0, args.seed),
        ),
    ];
    println!(
        "{:<16} {:<20} {:>8} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "workload",
        "contender",
        "queries",
        "p50 ns",
        "p99 ns",
        "p99.9 ns",
        "max ns",
        "mean ns",
        "batch ns"
    );
    let mut verdicts = Vec::new();
    for (name, targets) in &workloads {
        let answered = targets
            .iter()
            .filter(|t| table.query_target(t).status == Status::Ok)
            .count();
        let table_times = timer.time_each(targets, |t| table.query_target(t));
        let table_batch = Timer::batch_mean_ns(targets, |t| table.query_target(t));
        let kd_times = timer.time_each(targets, |t| kd.predict(t));
        let kd_batch = Timer::batch_mean_ns(targets, |t| kd.predict(t));
        let few = &targets[..args.reference_queries.min(targets.len())];
        let reference_times = timer.time_each(few, |t| reference::predict(&records, &params, t));
        let reference_batch =
            Timer::batch_mean_ns(few, |t| reference::predict(&records, &params, t));
        let rows = [
            ("table", table_times, table_batch),
            ("(b) k-d tree", kd_times, kd_batch),
            ("(a) brute force", reference_times, reference_batch),
        ];
        let mut summaries = Vec::new();
        for (contender, times, batch) in rows {
            let s = Summary::of(times).context("no queries to time")?;
            println!(
                "{name:<16} {contender:<20} {:>8} {:>10.0} {:>10.0} {:>10.0} {:>10.0} {:>10.0} {:>10.0}",
                s.count, s.p50_ns, s.p99_ns, s.p999_ns, s.max_ns, s.mean_ns, batch
            );
            summaries.push(s);
        }
        let (t, k) = (summaries[0], summaries[1]);
        verdicts.push(format!(
            "{name}: {answered} of {} targets answered; table p50 {:.0} ns, p99 {:.0} ns, \
             {:.1}x faster than the k-d tree at p50, {:.1}x at p99; {}",
            targets.len(),
            t.p50_ns,
            t.p99_ns,
            k.p50_ns / t.p50_ns.max(1.0),
            k.p99_ns / t.p99_ns.max(1.0),
            latency::agreement(&table, &kd, &records, targets, args.reference_queries),
        ));
    }
    println!();
    for v in verdicts {
        println!("{v}");
    }

    println!("\nopen ({} runs each)", args.open_repeats);
    println!("{:<44} {:>12} {:>12}", "", "median us", "max us");
    let path = &args.table;
    let open_rows: [(&str, Vec<Duration>); 4] = [
        (
            "mmap + full validation (Table::open)",
            latency::time_runs(args.open_repeats, || {
                // SAFETY: the file is not modified while this benchmark runs.
                unsafe { Table::open(path) }.map(|t| t.sample_count())
            }),
        ),
        (
            "read + full validation (Table::from_vec)",
            latency::time_runs(args.open_repeats, || {
                std::fs::read(path)
                    .ok()
                    .and_then(|b| Table::from_vec(b).ok().map(|t| t.sample_count()))
            }),
        ),
        (
            "(c) read + deserialise owned copy (rkyv)",
            latency::time_runs(args.open_repeats, || latency::deserialise_owned(path)),
        ),
        (
            "(b) start-up: build the k-d tree",
            latency::time_runs(args.open_repeats, || {
                KdTreeMethod::new(records.clone(), params)
            }),
        ),
    ];
    for (name, runs) in open_rows {
        println!(
            "{name:<44} {:>12.1} {:>12.1}",
            micros(runs[runs.len() / 2]),
            micros(runs[runs.len() - 1])
        );
    }
    Ok(())
}

fn micros(d: Duration) -> f64 {
    d.as_nanos() as f64 / 1e3
}

/// A hybrid table answers only with the joint angles the controller will use, which only
/// the controller's inverse kinematics knows for an arbitrary target: the workload is the
/// samples' own poses, each target moved by up to 5 mm along every axis and queried with
/// that sample's joint angles (model evaluation plus interpolated residual).
fn bench_hybrid<D: AsRef<[u8]>>(
    table: &Table<D>,
    timer: &Timer,
    queries: usize,
    seed: u64,
) -> anyhow::Result<()> {
    let inputs = latency::hybrid_workload(table, queries, seed)
        .context("the hybrid table carries no joint angles")?;
    let answered = inputs
        .iter()
        .filter(|(t, q)| table.query_with_joints(t, q).status == Status::Ok)
        .count();
    let times = timer.time_each(&inputs, |(t, q)| table.query_with_joints(t, q));
    let batch = Timer::batch_mean_ns(&inputs, |(t, q)| table.query_with_joints(t, q));
    let s = Summary::of(times).context("no queries to time")?;
    println!(
        "hybrid table: query_with_joints at the samples' poses moved by up to 5 mm, \
         with their joint angles ({answered} of {} answered)",
        inputs.len()
    );
    println!(
        "{:>8} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "queries", "p50 ns", "p99 ns", "p99.9 ns", "max ns", "mean ns", "batch ns"
    );
    println!(
        "{:>8} {:>10.0} {:>10.0} {:>10.0} {:>10.0} {:>10.0} {:>10.0}",
        s.count, s.p50_ns, s.p99_ns, s.p999_ns, s.max_ns, s.mean_ns, batch
    );
    Ok(())
}
