//! A real hybrid table (the UR5's, `tables/compat/v2/ur5_hybrid.tbl`): the calibrated
//! model answers everywhere, the residual where the samples are, fading without a jump
//! across the last cell, the grid box's faces and out to the fade length.

use adwi_runtime::{AlignedBytes, Residual, Status, Table, Target};
use proptest::prelude::*;

fn ur5_hybrid() -> Table<AlignedBytes> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tables/compat/v2/ur5_hybrid.tbl"
    );
    Table::from_vec(std::fs::read(path).unwrap()).unwrap()
}

/// A posture of the UR5 samples (the first of the shipped grid), degrees.
const Q_DEG: [f64; 6] = [
    -22.933297, -43.719156, 135.397847, -94.740321, 55.416785, -5.552225,
];

/// The largest change of the served correction over steps of `step_mm` along a line.
fn largest_step_mm(
    table: &Table<AlignedBytes>,
    q: &[f64; 6],
    from: [f64; 3],
    to: [f64; 3],
    step_mm: f64,
) -> (f64, [usize; 3]) {
    let length_mm = adwi_runtime::method::distance_mm(from, to);
    let steps = (length_mm / step_mm).ceil() as usize;
    let mut largest = 0.0f64;
    let mut flags = [0usize; 3];
    let mut previous: Option<[f64; 3]> = None;
    for i in 0..=steps {
        let t = i as f64 / steps as f64;
        let p = [0, 1, 2].map(|a| from[a] + t * (to[a] - from[a]));
        let c = table.query_with_joints(&Target::at(p), q);
        assert_eq!(c.status, Status::Ok, "at {p:?}");
        flags[c.residual as usize] += 1;
        if let Some(prev) = previous {
            largest = largest.max(adwi_runtime::method::distance_mm(prev, c.position_error_mm));
        }
        previous = Some(c.position_error_mm);
    }
    (largest, flags)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Lines from the nominal TCP's position at `Q` (inside the samples) out through the
    /// grid box, each as far as the joints are allowed from their target: every step of
    /// 0.01 mm changes the correction by at most 1 µm.
    #[test]
    fn the_served_hybrid_correction_moves_at_most_1_um_per_10_um_step(
        direction in prop::array::uniform3(-1.0..1.0f64),
    ) {
        let norm = direction.iter().map(|v| v * v).sum::<f64>().sqrt();
        prop_assume!(norm > 0.1);
        let table = ur5_hybrid();
        let q = Q_DEG.map(f64::to_radians);
        let start = table.model().unwrap().nominal().tcp_pose(&q).unwrap().translation_mm;
        let reach_mm = 0.999 * table.joints_tolerance_mm().unwrap();
        let end = [0, 1, 2].map(|a| start[a] + reach_mm * direction[a] / norm);
        let (largest, _) = largest_step_mm(&table, &q, start, end, 0.01);
        prop_assert!(largest <= 1e-3, "{largest} mm");
    }
}

/// Postures all over the UR5's joint space whose nominal TCP lies beyond the fade: each is
/// answered `ok`, `model_only`, with the model alone (calibrated FK − nominal FK).
#[test]
fn beyond_the_fade_the_answer_is_the_model_alone() {
    let table = ur5_hybrid();
    let model = table.model().unwrap();
    let grid = table.grid();
    let (low, high) = (grid.origin_mm, grid.max_mm());
    let fade_mm = adwi_runtime::served::fade_length_mm(grid.cell_mm);
    let mut far = 0;
    for i in 0..4096u32 {
        // A deterministic spread of postures.
        let q: [f64; 6] = std::array::from_fn(|j| {
            let x = (i as f64 * (0.618_034 + j as f64 * 0.414_214)).fract();
            std::f64::consts::PI * (2.0 * x - 1.0)
        });
        let p = model.nominal().tcp_pose(&q).unwrap().translation_mm;
        let outside: f64 = (0..3)
            .map(|a| (low[a] - p[a]).max(p[a] - high[a]).max(0.0).powi(2))
            .sum::<f64>()
            .sqrt();
        if outside <= fade_mm {
            continue;
        }
        far += 1;
        let calibrated = model
            .calibrated()
            .loaded_tcp_pose(&q)
            .unwrap()
            .translation_mm;
        for c in [
            table.query_with_joints(&Target::at(p), &q),
            table.exact().query_with_joints(&Target::at(p), &q),
        ] {
            assert_eq!(
                (c.status, c.residual),
                (Status::Ok, Residual::ModelOnly),
                "{p:?}"
            );
            for a in 0..3 {
                let want = calibrated[a] - p[a];
                assert!(
                    (c.position_error_mm[a] - want).abs() <= 1e-12,
                    "{c:?} vs {want}"
                );
            }
        }
    }
    assert!(far > 1000, "{far} postures beyond the fade");
}

/// Joints in degrees where radians are taken put the tool far from the target: refused.
#[test]
fn joints_in_the_wrong_unit_are_a_mismatch() {
    let table = ur5_hybrid();
    let q = Q_DEG.map(f64::to_radians);
    let p = table
        .model()
        .unwrap()
        .nominal()
        .tcp_pose(&q)
        .unwrap()
        .translation_mm;
    let target = Target::at(p);
    assert_eq!(table.query_with_joints(&target, &q).status, Status::Ok);
    for wrong in [Q_DEG, q.map(f64::to_radians)] {
        for c in [
            table.query_with_joints(&target, &wrong),
            table.exact().query_with_joints(&target, &wrong),
        ] {
            assert_eq!(c.status, Status::JointsMismatch);
            assert_eq!(c.position_error_mm, [0.0; 3]);
        }
    }
    assert_eq!(table.joints_tolerance_mm(), Some(200.0));
}

/// A position-only table refuses where it has no value, as it always did.
#[test]
fn position_only_tables_still_refuse_outside_the_grid_and_uncovered_cells() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tables/compat/v2/worked_example.tbl"
    );
    let table = Table::from_vec(std::fs::read(path).unwrap()).unwrap();
    assert_eq!(table.joints_tolerance_mm(), None);
    let outside = table.query([3000.0, 700.0, 1000.0]);
    assert_eq!(outside.status, Status::OutsideGrid);
    // 30 of the 125 cells are served: the others refuse.
    let grid = *table.grid();
    let mut uncovered = 0;
    for k in 0..125 {
        let cell = [k % 5, (k / 5) % 5, k / 25];
        let p = [0, 1, 2].map(|a| grid.origin_mm[a] + (cell[a] as f64 + 0.5) * grid.cell_mm);
        let c = table.query(p);
        match c.status {
            Status::Ok => assert_eq!(c.residual, Residual::Full),
            status => {
                assert_eq!(status, Status::UncoveredCell, "{p:?}");
                uncovered += 1;
            }
        }
    }
    assert_eq!(uncovered, 95);
}
