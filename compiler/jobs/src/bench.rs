//! The bench job: query and open latency of a table's two tiers, next to a k-d tree and
//! the brute force (`tablec bench`).

use std::path::{Path, PathBuf};
use std::time::Duration;

use adwi_eval::latency::{self, BenchOptions, KdTreeMethod, Summary, Timer, WorkloadResult};
use adwi_output::OutputPlan;
use adwi_runtime::Table;
use memmap2::Mmap;
use serde::{Deserialize, Serialize};

use crate::inputs::open_table;
use crate::JobError;

/// The most timed queries per workload: each holds a target, its joint values and a time,
/// and ten times the default is enough for a stable p99.9.
pub const MAX_QUERIES: usize = 1_000_000;

/// The most timed openings of the table per way of opening it.
pub const MAX_OPEN_REPEATS: usize = 10_000;

/// Query and open latency: every option of `tablec bench`.
#[derive(clap::Args, Deserialize, Debug, Clone)]
#[serde(default)]
pub struct BenchArgs {
    /// The table.
    pub table: PathBuf,
    /// Timed queries per workload for the table's tiers and the k-d tree.
    #[arg(long, default_value_t = 100_000)]
    pub queries: usize,
    /// Timed queries per workload for the brute-force reference (slow: every sample per
    /// query).
    #[arg(long, default_value_t = 2_000)]
    pub reference_queries: usize,
    /// Timed repetitions of each way of opening the table.
    #[arg(long, default_value_t = 20)]
    pub open_repeats: usize,
    /// Seed of the random targets and the trajectory.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also write the percentiles as JSON: {"random": {...}, "trajectory": {...}}, each
    /// with the contenders "trilinear", "exact", "kdtree" and "brute", each
    /// {"p50_ns": .., "p99_ns": ..}.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

impl Default for BenchArgs {
    fn default() -> BenchArgs {
        BenchArgs {
            table: PathBuf::new(),
            queries: 100_000,
            reference_queries: 2_000,
            open_repeats: 20,
            seed: 1,
            json: None,
        }
    }
}

/// A benchmark checked, its table open and its output checked, ready to run.
pub struct BenchJob {
    args: BenchArgs,
    table: Table<Mmap>,
    outputs: OutputPlan,
}

/// What the benchmark measured.
#[derive(Debug, Clone, Serialize)]
pub struct Benched {
    /// The table, as given.
    pub table: PathBuf,
    /// Its samples.
    pub samples: usize,
    /// Its grid's cells.
    pub cells: usize,
    /// Their edge, mm.
    pub cell_mm: f64,
    /// k: at most this many neighbours.
    pub max_neighbours: u32,
    /// ε, mm.
    pub radius_mm: f64,
    /// Whether the table has a served tier (otherwise `trilinear` is the exact tier).
    pub has_served_field: bool,
    /// A hybrid table's model part on this processor: how many lanes wide its chains walk
    /// (`PreparedModel::walk_lanes`: 4 with AVX2, 2 otherwise, 1 apart); `None` for a
    /// position-only table.
    pub model_walk_lanes: Option<u32>,
    /// The cost of an empty timed region, subtracted from every time, ns.
    pub clock_overhead_ns: f64,
    /// The two workloads, `random` and `trajectory`.
    pub workloads: Vec<Workload>,
    /// Timed repetitions of each way of opening the table.
    pub open_repeats: usize,
    /// Each way of opening the table, in report order.
    pub open: Vec<OpenTiming>,
    /// The table's bytes validated per second at the median of the memory map's openings,
    /// GB/s.
    pub validated_gb_per_s: f64,
    /// The files written (the JSON, when asked for).
    pub written: Vec<PathBuf>,
}

/// One workload's measurements.
#[derive(Debug, Clone, Serialize)]
pub struct Workload {
    /// `random` or `trajectory`.
    pub name: &'static str,
    /// Targets timed.
    pub targets: usize,
    /// Targets the served tier answered.
    pub answered_served: usize,
    /// Targets the exact tier answered.
    pub answered_exact: usize,
    /// Per contender, in the order trilinear, exact, kdtree, brute.
    pub timings: Vec<Timing>,
    /// Of the targets compared, how many the k-d tree answered exactly as the exact tier.
    pub kdtree_agreement: Agreement,
    /// The same for the brute force, on its fewer targets.
    pub brute_agreement: Agreement,
}

/// One contender's times on a workload.
#[derive(Debug, Clone, Serialize)]
pub struct Timing {
    /// `trilinear`, `exact`, `kdtree` or `brute`.
    pub contender: &'static str,
    /// Per-query percentiles.
    #[serde(flatten)]
    pub summary: Summary,
    /// The mean per query of one batch timed as a whole, ns: a check on the overhead
    /// correction.
    pub batch_ns: f64,
}

/// Answers identical (same status, same bits) to the exact tier's, out of how many.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Agreement {
    /// Identical answers.
    pub same: usize,
    /// Targets compared.
    pub of: usize,
}

/// The times of one way of opening the table.
#[derive(Debug, Clone, Serialize)]
pub struct OpenTiming {
    /// The way, in words.
    pub way: &'static str,
    /// The median run, µs.
    pub median_us: f64,
    /// The slowest run, µs.
    pub max_us: f64,
}

impl BenchJob {
    /// Checks the counts and the JSON output, then opens the table.
    ///
    /// # Errors
    ///
    /// [`JobError::Options`] for a count of nothing or beyond [`MAX_QUERIES`] or
    /// [`MAX_OPEN_REPEATS`], [`JobError::Output`], [`JobError::Table`].
    pub fn new(args: BenchArgs) -> Result<BenchJob, JobError> {
        for (name, count, max) in [
            ("queries", args.queries, MAX_QUERIES),
            ("reference_queries", args.reference_queries, MAX_QUERIES),
            ("open_repeats", args.open_repeats, MAX_OPEN_REPEATS),
        ] {
            if count == 0 || count > max {
                return Err(JobError::option(name, format!("{count}: give 1 to {max}")));
            }
        }
        let outputs = OutputPlan::check(
            &args.json.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
            &[&args.table],
        )?;
        let table = open_table(&args.table)?;
        Ok(BenchJob {
            args,
            table,
            outputs,
        })
    }

    /// Times the queries, writes the JSON, then times the openings.
    ///
    /// # Errors
    ///
    /// [`JobError::Bench`] when there is no workload (a hybrid table without a pose in
    /// its grid, or bytes changed since the table was opened), [`JobError::Output`].
    pub fn run(self) -> Result<Benched, JobError> {
        let BenchJob {
            args,
            table,
            outputs,
        } = self;
        let params = *table.method();
        let grid = *table.grid();
        let timer = Timer::calibrate();
        let options = BenchOptions {
            queries: args.queries,
            reference_queries: args.reference_queries,
            seed: args.seed,
        };
        let results = latency::bench_queries(&table, &timer, &options).ok_or_else(|| {
            JobError::Bench(
                "no workload: a hybrid table without a pose in its grid, or changed bytes".into(),
            )
        })?;
        let mut written = Vec::new();
        if let Some(path) = &args.json {
            outputs.write(&[(path, json(&results).as_bytes())])?;
            written.push(path.clone());
        }
        let (open, validated_gb_per_s) = time_openings(&table, &args.table, args.open_repeats);
        Ok(Benched {
            table: args.table.clone(),
            samples: table.sample_count(),
            cells: grid.cell_count().unwrap_or(0),
            cell_mm: grid.cell_mm,
            max_neighbours: params.max_neighbours,
            radius_mm: params.radius_mm,
            has_served_field: table.has_served_field(),
            model_walk_lanes: table.model().map(|m| m.walk_lanes()),
            clock_overhead_ns: timer.overhead_ns,
            workloads: results.iter().map(workload).collect(),
            open_repeats: args.open_repeats,
            open,
            validated_gb_per_s,
            written,
        })
    }
}

/// A workload's figures, named.
fn workload(w: &WorkloadResult) -> Workload {
    let agreement = |(same, of): (usize, usize)| Agreement { same, of };
    Workload {
        name: w.name,
        targets: w.targets,
        answered_served: w.answered.0,
        answered_exact: w.answered.1,
        timings: w
            .timings
            .iter()
            .map(|&(contender, summary, batch_ns)| Timing {
                contender: contender.name(),
                summary,
                batch_ns,
            })
            .collect(),
        kdtree_agreement: agreement(w.agreement[0]),
        brute_agreement: agreement(w.agreement[1]),
    }
}

/// Times each way of opening the table at `path`; with the bytes validated per second at
/// the memory map's median.
fn time_openings(table: &Table<Mmap>, path: &Path, repeats: usize) -> (Vec<OpenTiming>, f64) {
    let params = *table.method();
    let records = latency::records_of(table);
    let runs: [(&'static str, Vec<Duration>); 4] = [
        (
            "mmap + full validation (Table::open)",
            latency::time_runs(repeats, || {
                // SAFETY: the file is not modified while this benchmark runs.
                unsafe { Table::open(path) }.map(|t| t.sample_count())
            }),
        ),
        (
            "read + full validation (Table::from_vec)",
            latency::time_runs(repeats, || {
                std::fs::read(path)
                    .ok()
                    .and_then(|b| Table::from_vec(b).ok().map(|t| t.sample_count()))
            }),
        ),
        (
            "read + deserialise an owned copy (rkyv)",
            latency::time_runs(repeats, || latency::deserialise_owned(path)),
        ),
        (
            "k-d tree start-up: build the tree",
            latency::time_runs(repeats, || KdTreeMethod::new(records.clone(), params)),
        ),
    ];
    let bytes = std::fs::metadata(path).map_or(0, |m| m.len());
    let mmap_median = runs[0].1[runs[0].1.len() / 2];
    let gb_per_s = bytes as f64 / mmap_median.as_secs_f64().max(1e-12) / 1e9;
    let open = runs
        .into_iter()
        .map(|(way, runs)| OpenTiming {
            way,
            median_us: micros(runs[runs.len() / 2]),
            max_us: micros(runs[runs.len() - 1]),
        })
        .collect();
    (open, gb_per_s)
}

fn micros(d: Duration) -> f64 {
    d.as_nanos() as f64 / 1e3
}

/// `{"random": {"trilinear": {"p50_ns": .., "p99_ns": ..}, ...}, "trajectory": {...}}`.
fn json(results: &[WorkloadResult]) -> String {
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

#[cfg(test)]
mod tests {
    use clap::Parser;
    use serde::de::value::{Error, MapDeserializer};

    use super::*;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: BenchArgs,
    }

    /// clap's defaults are the struct's `Default`, which Python's keywords start from.
    #[test]
    fn the_command_line_and_python_have_the_same_defaults() {
        let parsed = Cli::parse_from(["bench", "t.tbl"]).args;
        let mut expected = BenchArgs::deserialize(MapDeserializer::<_, Error>::new(
            std::iter::empty::<(&str, &str)>(),
        ))
        .unwrap();
        expected.table = "t.tbl".into();
        assert_eq!(format!("{parsed:?}"), format!("{expected:?}"));
        let default = BenchArgs {
            table: "t.tbl".into(),
            ..BenchArgs::default()
        };
        assert_eq!(format!("{parsed:?}"), format!("{default:?}"));
    }

    /// No query, no reference query, no opening, or counts that would not fit in memory
    /// or time: refused as options before the table is read (it does not exist here).
    #[test]
    fn counts_are_refused_before_the_table_is_opened() {
        let missing = BenchArgs {
            table: "/nonexistent/t.tbl".into(),
            ..BenchArgs::default()
        };
        for args in [
            BenchArgs {
                queries: 0,
                ..missing.clone()
            },
            BenchArgs {
                reference_queries: 0,
                ..missing.clone()
            },
            BenchArgs {
                open_repeats: 0,
                ..missing.clone()
            },
            BenchArgs {
                queries: usize::MAX,
                ..missing.clone()
            },
        ] {
            let e = BenchJob::new(args).err().unwrap();
            assert!(matches!(e, JobError::Options(_)), "{e}");
        }
        let e = BenchJob::new(missing).err().unwrap();
        assert!(matches!(e, JobError::Table { .. }), "{e}");
    }
}
