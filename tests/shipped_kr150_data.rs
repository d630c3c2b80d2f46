//! The shipped KUKA KR150-2 sample files regenerate byte for byte from their robot,
//! scenario and plan, exactly as `tables/kr150-2/README.md` says.

use std::path::{Path, PathBuf};

use adwi_robot::Robot;
use adwi_simulate::{
    describe, position_error_stats_mm, simulate, write_csv, Positions, SamplingPlan, Scenario,
};

fn shipped(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tables/kr150-2")
        .join(name)
}

/// The plan of the README's commands: the 1350..2150 × 50..850 × 850..1650 mm box,
/// tool A 0, B 90, C 0, the configuration closest to home.
fn plan(positions: Positions, seed: u64) -> SamplingPlan {
    SamplingPlan {
        positions,
        abc_deg: [0.0, 90.0, 0.0],
        orientation_spread_deg: 0.0,
        config: None,
        seed,
    }
}

const MIN_MM: [f64; 3] = [1350.0, 50.0, 850.0];
const MAX_MM: [f64; 3] = [2150.0, 850.0, 1650.0];

fn regenerate_and_compare(file_name: &str, plan: &SamplingPlan) {
    let robot = Robot::load(shipped("robot.toml")).unwrap();
    let scenario = Scenario::load(shipped("scenario.toml")).unwrap();
    let samples = simulate(&robot, &scenario, plan).unwrap();

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(file_name);
    let file = std::fs::File::create(&path).unwrap();
    write_csv(&samples, &describe(&robot, "scenario.toml", plan), file).unwrap();

    let regenerated = std::fs::read(&path).unwrap();
    let original = std::fs::read(shipped(file_name)).unwrap();
    if regenerated != original {
        let first_difference = regenerated
            .iter()
            .zip(&original)
            .position(|(a, b)| a != b)
            .unwrap_or(regenerated.len().min(original.len()));
        panic!(
            "{file_name} differs from its regeneration at byte {first_difference} \
             (lengths {} and {}): rerun the commands in tables/kr150-2/README.md",
            original.len(),
            regenerated.len()
        );
    }

    // The scenario is sized to the paper's 1-3 mm of uncompensated error.
    let (mean_mm, max_mm) = position_error_stats_mm(&samples);
    assert!((1.0..=3.0).contains(&mean_mm), "mean {mean_mm} mm");
    assert!(max_mm <= 3.0, "max {max_mm} mm");
}

#[test]
fn samples_csv_regenerates_byte_for_byte() {
    let lattice = Positions::Lattice {
        min_mm: MIN_MM,
        max_mm: MAX_MM,
        step_mm: 100.0,
    };
    regenerate_and_compare("samples.csv", &plan(lattice, 1));
}

#[test]
fn validation_csv_regenerates_byte_for_byte() {
    let random = Positions::Random {
        count: 1000,
        min_mm: MIN_MM,
        max_mm: MAX_MM,
    };
    regenerate_and_compare("validation.csv", &plan(random, 2));
}
