//! `tablec bench`: the bench job ([`adwi_jobs::BenchJob`]), its percentiles and its
//! openings printed as tables, with the method in words.

use adwi_jobs::{BenchArgs, BenchJob};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: BenchArgs,
}

const METHOD: &str = "\
Method: single thread; each query timed on its own with std::time::Instant, minus the
median cost of an empty timed region; one untimed warm-up pass first. Percentiles are
nearest-rank over all timed queries. 'batch' is the mean per query of one untimed-per-call
batch, a check on the overhead correction. Workloads: targets uniform in the table's grid,
and a trajectory of targets 1 mm apart (straight segments of 200 mm, reflected at the
grid's faces); for a hybrid table, random joint poses whose tool lies in the grid (each
joint within the angles the samples span when the table records them, format version 6,
else within +-pi), and paths of small joint steps from them. Contenders: the served field (trilinear); the exact
tier; a k-d tree (kiddo, built at start-up) finding every sample within epsilon, then the
same selection and weights (adwi_runtime::method); the brute-force reference over every
sample. Open: memory map + full validation vs. reading the file and deserialising an owned
copy (rkyv validation, no semantic checks).";

pub fn run(args: Args) -> anyhow::Result<()> {
    let b = BenchJob::new(args.job)?.run()?;
    println!("{METHOD}\n");
    println!(
        "table {}: {} samples, {} cells of {:.3} mm, k = {}, epsilon = {:.3} mm{}",
        b.table.display(),
        b.samples,
        b.cells,
        b.cell_mm,
        b.max_neighbours,
        b.radius_mm,
        if b.has_served_field {
            ""
        } else {
            " (no served tier: 'trilinear' is the exact tier)"
        }
    );
    if let Some(lanes) = b.model_walk_lanes {
        let how = match lanes {
            4 => "4 lanes wide (AVX2)",
            2 => "2 lanes wide (this processor has no AVX2; the same answers)",
            _ => "one chain at a time (gravity compliance or joints of other kinds)",
        };
        println!("model part: both chains walked {how}");
    }
    println!(
        "clock overhead {:.1} ns per timed region\n",
        b.clock_overhead_ns
    );
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
    for w in &b.workloads {
        for t in &w.timings {
            let s = &t.summary;
            println!(
                "{:<11} {:<10} {:>8} {:>10.0} {:>10.0} {:>10.0} {:>10.0} {:>10.0} {:>10.0}",
                w.name,
                t.contender,
                s.count,
                s.p50_ns,
                s.p99_ns,
                s.p999_ns,
                s.max_ns,
                s.mean_ns,
                t.batch_ns
            );
        }
    }
    println!();
    for w in &b.workloads {
        let p50 = |i: usize| w.timings[i].summary.p50_ns.max(1.0);
        let p99 = |i: usize| w.timings[i].summary.p99_ns.max(1.0);
        println!(
            "{}: {} targets, {} answered by the served field, {} by the exact tier; the k-d \
             tree is {:.1}x the trilinear p50 ({:.1}x at p99) and {:.1}x the exact p50 ({:.1}x \
             at p99); exact answers identical to the k-d tree's {}/{}, to the brute force's {}/{}",
            w.name,
            w.targets,
            w.answered_served,
            w.answered_exact,
            p50(2) / p50(0),
            p99(2) / p99(0),
            p50(2) / p50(1),
            p99(2) / p99(1),
            w.kdtree_agreement.same,
            w.kdtree_agreement.of,
            w.brute_agreement.same,
            w.brute_agreement.of,
        );
    }
    println!("\nopen ({} runs each)", b.open_repeats);
    println!("{:<44} {:>12} {:>12}", "", "median us", "max us");
    for (i, o) in b.open.iter().enumerate() {
        println!("{:<44} {:>12.1} {:>12.1}", o.way, o.median_us, o.max_us);
        // The memory map's row comes first.
        if i == 0 {
            println!(
                "{:<44} {:>12.2}",
                "  (validated GB/s at the median)", b.validated_gb_per_s
            );
        }
    }
    Ok(())
}
