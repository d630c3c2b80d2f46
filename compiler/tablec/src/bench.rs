//! `tablec bench`: query and open latency of a table's two tiers, next to a k-d tree and
//! the brute force.

use std::path::PathBuf;
use std::time::Duration;

use adwi_eval::latency::{self, BenchOptions, KdTreeMethod, Timer};
use adwi_runtime::Table;
use anyhow::Context;

#[derive(clap::Args)]
pub struct Args {
    /// The table.
    table: PathBuf,
    /// Timed queries per workload for the table's tiers and the k-d tree.
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
    /// Also write the percentiles as JSON: {"random": {...}, "trajectory": {...}}, each
    /// with the contenders "trilinear", "exact", "kdtree" and "brute", each
    /// {"p50_ns": .., "p99_ns": ..}.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
}

const METHOD: &str = "\
Method: single thread; each query timed on its own with std::time::Instant, minus the
median cost of an empty timed region; one untimed warm-up pass first. Percentiles are
nearest-rank over all timed queries. 'batch' is the mean per query of one untimed-per-call
batch, a check on the overhead correction. Workloads: targets uniform in the table's grid,
and a trajectory of targets 1 mm apart (straight segments of 200 mm, reflected at the
grid's faces); for a hybrid table, random joint poses whose tool lies in the grid, and
paths of small joint steps from them. Contenders: the served field (trilinear); the exact
tier; a k-d tree (kiddo, built at start-up) finding every sample within epsilon, then the
same selection and weights (adwi_runtime::method); the brute-force reference over every
sample. Open: memory map + full validation vs. reading the file and deserialising an owned
copy (rkyv validation, no semantic checks).";

pub fn run(args: Args) -> anyhow::Result<()> {
    let outputs = adwi_output::OutputPlan::check(
        &args.json.iter().map(|p| p.as_path()).collect::<Vec<_>>(),
        &[&args.table],
    )?;
    let table = crate::open_table(&args.table)?;
    let params = *table.method();
    let grid = *table.grid();
    println!("{METHOD}\n");
    println!(
        "table {}: {} samples, {} cells of {} mm, k = {}, epsilon = {} mm{}",
        args.table.display(),
        table.sample_count(),
        grid.cell_count().unwrap_or(0),
        grid.cell_mm,
        params.max_neighbours,
        params.radius_mm,
        if table.has_served_field() {
            ""
        } else {
            " (no served tier: 'trilinear' is the exact tier)"
        }
    );
    let timer = Timer::calibrate();
    println!(
        "clock overhead {:.1} ns per timed region\n",
        timer.overhead_ns
    );
    let options = BenchOptions {
        queries: args.queries,
        reference_queries: args.reference_queries,
        seed: args.seed,
    };
    let results = latency::bench_queries(&table, &timer, &options)
        .context("no workload: a hybrid table without a pose in its grid, or changed bytes")?;
    println!(
        "{:<11} {:<10} {:>8} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
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
    for w in &results {
        for (contender, s, batch) in &w.timings {
            println!(
                "{:<11} {:<10} {:>8} {:>10.0} {:>10.0} {:>10.0} {:>10.0} {:>10.0} {:>10.0}",
                w.name,
                contender.name(),
                s.count,
                s.p50_ns,
                s.p99_ns,
                s.p999_ns,
                s.max_ns,
                s.mean_ns,
                batch
            );
        }
    }
    println!();
    for w in &results {
        let p50 = |i: usize| w.timings[i].1.p50_ns.max(1.0);
        let p99 = |i: usize| w.timings[i].1.p99_ns.max(1.0);
        println!(
            "{}: {} targets, {} answered by the served field, {} by the exact tier; the k-d \
             tree is {:.1}x the trilinear p50 ({:.1}x at p99) and {:.1}x the exact p50 ({:.1}x \
             at p99); exact answers identical to the k-d tree's {}/{}, to the brute force's {}/{}",
            w.name,
            w.targets,
            w.answered.0,
            w.answered.1,
            p50(2) / p50(0),
            p99(2) / p99(0),
            p50(2) / p50(1),
            p99(2) / p99(1),
            w.agreement[0].0,
            w.agreement[0].1,
            w.agreement[1].0,
            w.agreement[1].1,
        );
    }
    if let Some(path) = &args.json {
        outputs.write(&[(path, json(&results).as_bytes())])?;
    }

    println!("\nopen ({} runs each)", args.open_repeats);
    println!("{:<44} {:>12} {:>12}", "", "median us", "max us");
    let path = &args.table;
    let records = latency::records_of(&table);
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
            "read + deserialise an owned copy (rkyv)",
            latency::time_runs(args.open_repeats, || latency::deserialise_owned(path)),
        ),
        (
            "k-d tree start-up: build the tree",
            latency::time_runs(args.open_repeats, || {
                KdTreeMethod::new(records.clone(), params)
            }),
        ),
    ];
    let bytes = std::fs::metadata(path).map_or(0, |m| m.len());
    for (name, runs) in open_rows {
        let median = runs[runs.len() / 2];
        println!(
            "{name:<44} {:>12.1} {:>12.1}",
            micros(median),
            micros(runs[runs.len() - 1])
        );
        if name.starts_with("mmap") {
            println!(
                "{:<44} {:>12.2}",
                "  (validated GB/s at the median)",
                bytes as f64 / median.as_secs_f64().max(1e-12) / 1e9
            );
        }
    }
    Ok(())
}

fn micros(d: Duration) -> f64 {
    d.as_nanos() as f64 / 1e3
}

/// `{"random": {"trilinear": {"p50_ns": .., "p99_ns": ..}, ...}, "trajectory": {...}}`.
fn json(results: &[latency::WorkloadResult]) -> String {
    let workloads: Vec<String> = results
        .iter()
        .map(|w| {
            let contenders: Vec<String> = w
                .timings
                .iter()
                .map(|(c, s, _)| {
                    format!(
                        "\"{}\": {{\"p50_ns\": {:.1}, \"p99_ns\": {:.1}}}",
                        c.name(),
                        s.p50_ns,
                        s.p99_ns
                    )
                })
                .collect();
            format!("\"{}\": {{{}}}", w.name, contenders.join(", "))
        })
        .collect();
    format!("{{{}}}\n", workloads.join(", "))
}
