//! Query and open latency of a table against what an integrator would do without one,
//! measured by criterion (`tablec bench` gives the per-query percentiles).
//!
//! The table is compiled from the shipped KR150-2 sample database
//! (`tables/kr150-2/samples.csv`, 729 samples on a 100 mm lattice) with the default
//! options. Groups:
//!
//! - `query/*`: one query at random targets in the grid, and along a trajectory of targets
//!   1 mm apart, for the table, a k-d tree (kiddo) with the same method, and the brute
//!   force reference;
//! - `open/*`: mapping and fully validating the table file vs. reading and deserialising
//!   an owned copy.
//!
//! Run: `cargo bench -p adwi-eval --bench latency`. Under `cargo test` it runs once in
//! criterion's test mode.

use std::hint::black_box;
use std::path::Path;

use adwi_compile::build::{compile, BuildOptions};
use adwi_compile::reference;
use adwi_eval::latency::{self, KdTreeMethod};
use adwi_output::write_atomically;
use adwi_runtime::format::{v2::TableData, HEADER_LEN};
use adwi_runtime::{AlignedBytes, Table, Target};
use adwi_samples::{read_samples, ColumnMap};
use criterion::{criterion_group, criterion_main, Criterion};

fn bench(c: &mut Criterion) {
    let csv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables/kr150-2/samples.csv");
    let samples = read_samples(&csv, &ColumnMap::default()).expect("shipped samples");
    let (bytes, _) = compile(&samples, &BuildOptions::default(), &|_| {}).expect("build");
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("kr150.tbl");
    write_atomically(&path, &bytes).expect("write the table");
    // SAFETY: the file is private to this benchmark and never modified while mapped.
    let table = unsafe { Table::open(&path) }.expect("open");
    let records = latency::records_of(&table);
    let params = *table.method();
    let kd = KdTreeMethod::new(records.clone(), params);
    let workloads: [(&str, Vec<Target>); 2] = [
        ("random", latency::random_targets(table.grid(), 4096, 1)),
        (
            "trajectory",
            latency::trajectory(table.grid(), 4096, 1.0, 1),
        ),
    ];

    let mut group = c.benchmark_group("query");
    for (name, targets) in &workloads {
        let mut i = 0;
        let mut next = || {
            i = (i + 1) % targets.len();
            &targets[i]
        };
        group.bench_function(format!("{name}/table"), |b| {
            b.iter(|| table.query_target(black_box(next())))
        });
        let mut i = 0;
        let mut next = || {
            i = (i + 1) % targets.len();
            &targets[i]
        };
        group.bench_function(format!("{name}/kd_tree"), |b| {
            b.iter(|| kd.predict(black_box(next())))
        });
        let mut i = 0;
        let mut next = || {
            i = (i + 1) % targets.len();
            &targets[i]
        };
        group.bench_function(format!("{name}/brute_force"), |b| {
            b.iter(|| reference::predict(&records, &params, black_box(next())))
        });
    }
    group.finish();

    let mut group = c.benchmark_group("open");
    group.sample_size(10);
    group.bench_function("mmap_and_validate", |b| {
        // SAFETY: as above.
        b.iter(|| unsafe { Table::open(&path) }.map(|t| t.sample_count()))
    });
    group.bench_function("read_and_deserialise", |b| {
        b.iter(|| {
            let bytes = std::fs::read(&path).expect("read");
            let aligned = AlignedBytes::copy_from(&bytes).expect("memory");
            rkyv::from_bytes::<TableData, rkyv::rancor::Error>(&aligned[HEADER_LEN..])
                .map(|d| d.samples.len())
        })
    });
    group.bench_function("kd_tree_start_up", |b| {
        b.iter(|| KdTreeMethod::new(records.clone(), params))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
