//! Mutated robot files and scenarios through the real `tablec`: `simulate` with a mutated
//! KR150-2 robot file or error scenario, then `calibrate` of what it wrote; `calibrate` of
//! the UR5's laser-tracker measurements with a mutated UR5 URDF (directly, or named by a
//! robot file). The end-to-end counterpart of the simulate crate's
//! `tests/robot_file_mutation.rs`, with the same mutations (`adwi_robot::testing`).
//!
//! Whatever the files: `tablec` exits 0 or 1 (never a panic's 101, never a signal), its
//! message is short, and every file it writes on success reads again — the samples as
//! samples (finite by the reader's checks), the calibrated robot file and URDF as robots.
//!
//! Runs for `ADWI_ROBOT_MUTATION_SECONDS` (default 3) of wall time from seed
//! `ADWI_ROBOT_MUTATION_SEED` (default 1); `ADWI_ROBOT_MUTATION_CASE=i` replays case `i`.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Output;
use std::time::{Duration, Instant};

use adwi_robot::testing::mutate;
use adwi_robot::{LinkNames, Robot};
use adwi_samples::{read_samples, ColumnMap};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{repo, tablec, ur5_grid, UR5_MAP};

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The longest message `tablec` may print for a refused input.
const MAX_STDERR_BYTES: usize = 8192;

/// What `tablec` did with a mutated input.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Outcome {
    Refused,
    Written,
}

/// Checks one run: exit 0 or 1, a short message; `Ok(true)` when it succeeded.
fn ran(what: &str, o: &Output) -> Result<bool, String> {
    let stderr = String::from_utf8_lossy(&o.stderr);
    if stderr.len() > MAX_STDERR_BYTES {
        return Err(format!("{what}: {} bytes on stderr", stderr.len()));
    }
    match o.status.code() {
        Some(0) => Ok(true),
        Some(1) if !stderr.trim().is_empty() => Ok(false),
        code => Err(format!("{what}: exit {code:?}: {stderr}")),
    }
}

/// The calibrated robot file and URDF `calibrate` wrote read again as robots.
fn written_robots_load(dir: &Path) -> Result<(), String> {
    Robot::load(dir.join("calibrated.toml"))
        .map_err(|e| format!("the calibrated robot file does not load: {e:#?}"))?;
    let tcp = LinkNames {
        base_link: None,
        tip_link: Some(adwi_robot::urdf::TCP_LINK.into()),
        flange_link: None,
    };
    Robot::load_with(dir.join("calibrated.urdf"), &tcp)
        .map_err(|e| format!("the calibrated URDF does not load: {e:#?}"))?;
    Ok(())
}

fn run_case(dir: &Path, seed: u64, case: u64) -> Result<Outcome, String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(case);
    let dir = dir.join(format!("case{case}"));
    std::fs::create_dir_all(&dir).unwrap();
    let read = |path: &str| std::fs::read_to_string(repo(path)).unwrap();
    let mutations = rng.gen_range(1..=3);
    let calibrate_out = ["-o", "calibrated.toml", "--urdf", "calibrated.urdf"];
    if rng.gen_bool(0.5) {
        // The KR150-2: a robot file or a scenario mutated, simulated, then calibrated.
        let (mut robot, mut scenario) = (
            read("tables/kr150-2/robot.toml"),
            read("tables/kr150-2/scenario.toml"),
        );
        let target = if rng.gen_bool(0.5) {
            &mut robot
        } else {
            &mut scenario
        };
        for _ in 0..mutations {
            mutate(target, false, &mut rng);
        }
        std::fs::write(dir.join("robot.toml"), &robot).unwrap();
        std::fs::write(dir.join("scenario.toml"), &scenario).unwrap();
        let o = tablec(
            &[
                "simulate",
                "--robot",
                "robot.toml",
                "--scenario",
                "scenario.toml",
                "--min",
                "1350,50,850",
                "--max",
                "2150,850,1650",
                "--random",
                "40",
                "--seed",
                &case.to_string(),
                "-o",
                "sim.csv",
            ],
            &dir,
        );
        if !ran("simulate", &o)? {
            return Ok(Outcome::Refused);
        }
        read_samples(&dir.join("sim.csv"), &ColumnMap::default())
            .map_err(|e| format!("the simulated samples do not read: {e}"))?;
        let mut args = vec!["calibrate", "sim.csv", "--robot", "robot.toml"];
        args.extend(calibrate_out);
        let o = tablec(&args, &dir);
        if !ran("calibrate", &o)? {
            return Ok(Outcome::Refused);
        }
        written_robots_load(&dir)?;
    } else {
        // The UR5: its URDF mutated, calibrated from the laser-tracker measurements, the
        // URDF named directly or by a robot file.
        let mut urdf = read("tables/ur5/robot.urdf");
        for _ in 0..mutations {
            mutate(&mut urdf, true, &mut rng);
        }
        std::fs::write(dir.join("robot.urdf"), &urdf).unwrap();
        std::fs::write(
            dir.join("robot.toml"),
            "name = \"UR5\"\nurdf = \"robot.urdf\"\n[tool]\ntranslation_mm = [0.0, 0.09, 31.0]\n",
        )
        .unwrap();
        let robot = if rng.gen_bool(0.5) {
            "robot.urdf"
        } else {
            "robot.toml"
        };
        let grid = ur5_grid();
        let mut args = vec![
            "calibrate",
            grid.to_str().unwrap(),
            "--columns",
            UR5_MAP,
            "--robot",
            robot,
        ];
        if rng.gen_bool(0.5) {
            args.push("--compliance");
        }
        args.extend(calibrate_out);
        let o = tablec(&args, &dir);
        if !ran("calibrate", &o)? {
            return Ok(Outcome::Refused);
        }
        written_robots_load(&dir)?;
    }
    Ok(Outcome::Written)
}

#[test]
fn tablec_never_crashes_nor_writes_non_finite_values_for_mutated_robot_files() {
    let seconds = env_or("ADWI_ROBOT_MUTATION_SECONDS", 3);
    let seed = env_or("ADWI_ROBOT_MUTATION_SEED", 1);
    let only: Option<u64> = std::env::var("ADWI_ROBOT_MUTATION_CASE")
        .ok()
        .and_then(|v| v.parse().ok());
    let dir = tempfile::tempdir().unwrap();
    let start = Instant::now();
    let mut counts: BTreeMap<Outcome, u64> = BTreeMap::new();
    let mut case = only.unwrap_or(0);
    let mut cases = 0;
    while only.is_some() || start.elapsed() < Duration::from_secs(seconds) {
        let rerun = format!("ADWI_ROBOT_MUTATION_SEED={seed} ADWI_ROBOT_MUTATION_CASE={case}");
        match run_case(dir.path(), seed, case) {
            Ok(outcome) => *counts.entry(outcome).or_insert(0) += 1,
            Err(wrong) => panic!("seed {seed}, case {case}: {wrong} (replay: {rerun})"),
        }
        let _ = std::fs::remove_dir_all(dir.path().join(format!("case{case}")));
        cases += 1;
        case += 1;
        if only.is_some() {
            break;
        }
    }
    eprintln!(
        "tablec robot mutation: seed {seed}, {cases} cases in {:.1} s: {counts:?}",
        start.elapsed().as_secs_f64()
    );
}
