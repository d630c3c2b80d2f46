//! A served query end to end, on the committed compatibility tables (so that the bench
//! needs no build of its own): where a query's time goes outside the model part
//! (`benches/model.rs` has that piece by piece).
//!
//! - `served/hybrid`: `Table::query_with_joints` of the version-4 UR5 hybrid table
//!   (`tables/compat/v4/ur5_hybrid.tbl`: the UR5's calibrated model, a method field over
//!   its residuals in 100 mm cells, the evidence recorded) at random joint poses whose
//!   nominal TCP lies in the grid: the model part, the checks, the evidence flag, the
//!   cell's 8 nodes and the last guard;
//! - `served/hybrid_exact`: the same queries by the exact tier (`Table::exact`);
//! - `served/hybrid_v6`: the same queries of the version-6 fixture
//!   (`tables/compat/v6/ur5_hybrid.tbl`, the same table with the joints its samples span,
//!   which bound its residual): most of these poses lie beyond them, where the residual
//!   fades to the model;
//! - `served/hybrid_within` and `served/hybrid_within_v6`: both tables at random joint
//!   poses within the angles the samples span (the poses a controller commands where the
//!   table was measured), the version-6 one checking them;
//! - `served/position_only`: `Table::query_target` of the version-2 position-only table
//!   (`tables/compat/v2/worked_example.tbl`) at random targets in its covered cells;
//! - `served/position_only_exact`: the same targets by the exact tier: the cell's
//!   candidates screened, the `k` nearest selected and weighed.
//!
//! The tables are small, so their cells stay in cache: `tablec bench` on a table of the
//! size a controller serves times the memory's part too.
//!
//! Run: `cargo bench -p adwi-runtime --bench served`. Under `cargo test` it runs once in
//! criterion's test mode.

use std::hint::black_box;

use adwi_runtime::testing::uniform;
use adwi_runtime::{AlignedBytes, Status, Table, Target};
use criterion::{criterion_group, criterion_main, Criterion};

fn table(path: &str) -> Table<AlignedBytes> {
    let path = format!("{}/../tables/compat/{path}", env!("CARGO_MANIFEST_DIR"));
    Table::from_vec(std::fs::read(path).expect("a committed table")).expect("a valid table")
}

fn bench(c: &mut Criterion) {
    let hybrid = table("v4/ur5_hybrid.tbl");
    let nominal = hybrid.model().expect("a hybrid table").nominal();
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut poses: Vec<(Target, [f64; 6])> = Vec::new();
    while poses.len() < 1024 {
        let q = [0; 6].map(|_| -std::f64::consts::PI + std::f64::consts::TAU * uniform(&mut state));
        let tcp = nominal.tcp_pose(&q).expect("six joints").translation_mm;
        let target = Target::at(tcp);
        if hybrid.query_with_joints(&target, &q).status == Status::Ok
            && hybrid.grid().cell_of(tcp).is_some()
        {
            poses.push((target, q));
        }
    }
    let bounded = table("v6/ur5_hybrid.tbl");
    let ranges = bounded
        .model()
        .expect("a hybrid table")
        .joint_terms()
        .range_rad;
    let mut within: Vec<(Target, [f64; 6])> = Vec::new();
    while within.len() < 1024 {
        let q: [f64; 6] = std::array::from_fn(|j| {
            ranges[j][0] + (ranges[j][1] - ranges[j][0]) * uniform(&mut state)
        });
        let tcp = nominal.tcp_pose(&q).expect("six joints").translation_mm;
        let target = Target::at(tcp);
        if bounded.query_with_joints(&target, &q).status == Status::Ok
            && bounded.grid().cell_of(tcp).is_some()
        {
            within.push((target, q));
        }
    }
    let position_only = table("v2/worked_example.tbl");
    let grid = *position_only.grid();
    let (lo, hi) = (grid.origin_mm, grid.max_mm());
    let mut targets = Vec::new();
    while targets.len() < 1024 {
        let p = [0, 1, 2].map(|a| lo[a] + (hi[a] - lo[a]) * uniform(&mut state));
        if position_only.query(p).status == Status::Ok {
            targets.push(Target::at(p));
        }
    }

    let mut group = c.benchmark_group("served");
    let mut i = 0;
    group.bench_function("hybrid", |b| {
        b.iter(|| {
            i = (i + 1) % poses.len();
            let (target, q) = black_box(&poses[i]);
            hybrid.query_with_joints(target, q)
        })
    });
    group.bench_function("hybrid_exact", |b| {
        b.iter(|| {
            i = (i + 1) % poses.len();
            let (target, q) = black_box(&poses[i]);
            hybrid.exact().query_with_joints(target, q)
        })
    });
    for (name, table, poses) in [
        ("hybrid_v6", &bounded, &poses),
        ("hybrid_within", &hybrid, &within),
        ("hybrid_within_v6", &bounded, &within),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                i = (i + 1) % poses.len();
                let (target, q) = black_box(&poses[i]);
                table.query_with_joints(target, q)
            })
        });
    }
    group.bench_function("position_only", |b| {
        b.iter(|| {
            i = (i + 1) % targets.len();
            position_only.query_target(black_box(&targets[i]))
        })
    });
    group.bench_function("position_only_exact", |b| {
        b.iter(|| {
            i = (i + 1) % targets.len();
            position_only.exact().query_target(black_box(&targets[i]))
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
