//! A latency guard that can fail and cannot flake: the table's query against the
//! brute-force reference (every sample's distance, sorted) on the same samples and targets,
//! timed in the same run, so that a busy machine slows both. The table answers from its
//! cell's precomputed list; a regression to a scan of every sample (or an allocation, a
//! lock) brings it to the reference's cost, and fails. `tablec bench` gives the figures.

use adwi_compile::build::{compile, BuildOptions};
use adwi_compile::reference;
use adwi_eval::latency::{Summary, Timer};
use adwi_runtime::{Status, Table, Target};
use adwi_samples::{parse_samples, ColumnMap};

use crate::common::SplitMix;

/// Samples per axis of the lattice: 4,096 samples, so that a scan of every one costs
/// microseconds where the table's answer costs a few hundred nanoseconds.
const PER_AXIS: usize = 16;
const SPACING_MM: f64 = 50.0;
/// How much faster than the brute force the table must answer, at the median: measured
/// ratios are in the hundreds; a table that scans its samples comes near 1.
const MIN_SPEEDUP: f64 = 10.0;

fn lattice() -> String {
    let mut rng = SplitMix(31);
    let mut csv = String::from("x,y,z,dx,dy,dz\n");
    for k in 0..PER_AXIS {
        for j in 0..PER_AXIS {
            for i in 0..PER_AXIS {
                let p = [i, j, k].map(|n| 1000.0 + n as f64 * SPACING_MM);
                let e = [0, 1, 2]
                    .map(|a| 0.5 * (p[(a + 1) % 3] * 2e-3).sin() + rng.uniform(-0.01, 0.01));
                csv += &format!("{},{},{},{},{},{}\n", p[0], p[1], p[2], e[0], e[1], e[2]);
            }
        }
    }
    csv
}

#[test]
fn a_query_is_far_faster_than_the_brute_force_in_the_same_run() {
    let csv = lattice();
    let samples = parse_samples(
        "lattice.csv".as_ref(),
        csv.as_bytes(),
        &ColumnMap::default(),
    )
    .unwrap();
    let (bytes, _) = compile(&samples, &BuildOptions::default(), &|_| {}).unwrap();
    let table = Table::from_vec(bytes).unwrap();
    let records = samples.records();
    let params = *table.method();
    let extent = SPACING_MM * (PER_AXIS - 1) as f64;
    let mut rng = SplitMix(32);
    let targets: Vec<Target> = (0..4_000)
        .map(|_| Target::at([0, 1, 2].map(|_| 1000.0 + rng.uniform(0.0, extent))))
        .collect();
    let answered = targets
        .iter()
        .filter(|t| table.query_target(t).status == Status::Ok)
        .count();
    assert!(answered > 3_900, "{answered} answered");

    let timer = Timer::calibrate();
    // Interleaved rounds, so that a burst of load on the machine falls on both.
    let (mut served, mut exact, mut brute) = (Vec::new(), Vec::new(), Vec::new());
    for chunk in targets.chunks(500) {
        served.extend(timer.time_each(chunk, |t| table.query_target(t)));
        exact.extend(timer.time_each(chunk, |t| table.exact().query_target(t)));
        brute.extend(timer.time_each(chunk, |t| reference::predict(&records, &params, t)));
    }
    let [served, exact, brute] = [served, exact, brute].map(|t| Summary::of(t).unwrap());
    eprintln!(
        "p50 / p99 ns: served {:.0} / {:.0}, exact {:.0} / {:.0}, brute force {:.0} / {:.0}",
        served.p50_ns, served.p99_ns, exact.p50_ns, exact.p99_ns, brute.p50_ns, brute.p99_ns
    );
    for (name, tier) in [("served", &served), ("exact", &exact)] {
        assert!(
            tier.p50_ns * MIN_SPEEDUP < brute.p50_ns,
            "{name} tier p50 {:.0} ns is not {MIN_SPEEDUP}x below the brute force's {:.0} ns",
            tier.p50_ns,
            brute.p50_ns
        );
        // The tail too: a slow path taken by one target in a hundred shows here.
        assert!(
            tier.p99_ns < brute.p50_ns,
            "{name} tier p99 {:.0} ns is above the brute force's median {:.0} ns",
            tier.p99_ns,
            brute.p50_ns
        );
    }
}
