//! Query latency of a compiled table against the brute-force reference.
//!
//! The table is built from a 16 × 16 × 16 lattice (4,096 samples, 50 mm spacing, ±5 mm
//! noise) 1-2 m from the base, with 12.5 mm cells; build time and table size are printed
//! before the measurements. Run: `cargo bench -p adwi-eval --bench query`.

use std::hint::black_box;
use std::time::Instant;

use adwi_compile::build::{compile, BuildOptions};
use adwi_compile::reference;
use adwi_runtime::{Table, Target};
use adwi_samples::SampleSet;
use criterion::{criterion_group, criterion_main, Criterion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const SIDE: usize = 16;
const SPACING_MM: f64 = 50.0;
const ORIGIN_MM: [f64; 3] = [1200.0, -400.0, 600.0];

fn noisy_lattice(rng: &mut ChaCha8Rng) -> SampleSet {
    let mut set = SampleSet::default();
    for i in 0..SIDE * SIDE * SIDE {
        let ijk = [i % SIDE, (i / SIDE) % SIDE, i / (SIDE * SIDE)];
        let nominal =
            [0, 1, 2].map(|a| ORIGIN_MM[a] + ijk[a] as f64 * SPACING_MM + rng.gen_range(-5.0..5.0));
        // A smooth error field of 1-3 mm, as a robot's.
        let error = [
            1.0 + 0.001 * nominal[0] + 0.2 * (nominal[1] / 300.0).sin(),
            0.5 + 0.0008 * nominal[2] - 0.3 * (nominal[0] / 400.0).cos(),
            -1.5 + 0.0005 * (nominal[0] + nominal[1]),
        ];
        set.nominal_mm.push(nominal);
        set.error_mm.push(error);
        set.lines.push(i as u64 + 2);
    }
    set
}

fn targets(rng: &mut ChaCha8Rng, n: usize) -> Vec<Target> {
    let extent = (SIDE - 1) as f64 * SPACING_MM;
    (0..n)
        .map(|_| Target::at([0, 1, 2].map(|a| ORIGIN_MM[a] + rng.gen_range(0.0..extent))))
        .collect()
}

fn bench(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let samples = noisy_lattice(&mut rng);
    let options = BuildOptions {
        cell_mm: Some(SPACING_MM / 4.0),
        ..BuildOptions::default()
    };
    let started = Instant::now();
    let (bytes, report) = compile(&samples, &options, &|_| {}).unwrap();
    eprintln!(
        "table: {} samples, {} cells, {} distinct lists (mean {:.1}, max {} per cell), \
         {} bytes, built in {:.2} s on {} threads",
        report.plan.samples,
        report.plan.cells(),
        report.distinct_lists,
        report.mean_list_len,
        report.max_list_len,
        bytes.len(),
        started.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    let table = Table::from_vec(bytes).unwrap();
    let targets = targets(&mut rng, 4096);
    let records = samples.records();
    let params = *table.method();

    let mut group = c.benchmark_group("query");
    let mut i = 0;
    group.bench_function("table", |b| {
        b.iter(|| {
            i = (i + 1) & 4095;
            black_box(table.query_target(black_box(&targets[i])))
        })
    });
    let mut i = 0;
    group.bench_function("compensate", |b| {
        b.iter(|| {
            i = (i + 1) & 4095;
            black_box(table.compensate(black_box(&targets[i]), 1e-6, 20))
        })
    });
    let mut i = 0;
    group.bench_function("reference_brute_force", |b| {
        b.iter(|| {
            i = (i + 1) & 4095;
            black_box(reference::predict(
                &records,
                &params,
                black_box(&targets[i]),
            ))
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
