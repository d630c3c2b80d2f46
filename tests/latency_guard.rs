//! A latency guard that cannot flake: bounds far above the measured figures (a few hundred
//! nanoseconds per query; `tablec bench` prints them), so that only a gross regression (an
//! allocation, a lock, a scan of every sample) fails it, never a busy machine.

use crate::common;

use adwi_eval::latency::{Summary, Timer};
use adwi_runtime::{Status, Table, Target};

#[test]
fn p99_query_latency_is_far_below_fifty_microseconds() {
    let table = Table::from_vec(common::lattice_table(21, 1.0)).unwrap();
    let targets: Vec<Target> = common::targets(22, 10_000)
        .into_iter()
        .map(Target::at)
        .collect();
    assert!(
        targets
            .iter()
            .filter(|t| table.query_target(t).status == Status::Ok)
            .count()
            > 9_000
    );
    let timer = Timer::calibrate();
    let s = Summary::of(timer.time_each(&targets, |t| table.query_target(t))).unwrap();
    assert!(s.p99_ns < 50_000.0, "{s:?}");
    assert!(s.p50_ns < 10_000.0, "{s:?}");
    let c = Summary::of(timer.time_each(&targets, |t| table.compensate(t, 1e-6, 20))).unwrap();
    assert!(c.p99_ns < 500_000.0, "{c:?}");
}
