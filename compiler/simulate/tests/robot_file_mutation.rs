//! Robot files (TOML and URDF) and error scenarios, mutated, through the library calls
//! `tablec simulate` and `tablec calibrate` make: loading (`Robot::load_with_files`, a
//! TOML file naming a URDF file too), `Scenario::from_toml_str`, `simulate`, the samples
//! read back from the written CSV, `identify`, and the calibrated robot written as a robot
//! file and as URDF and loaded again. A bounded, stable-Rust counterpart of a fuzzer, run
//! on every `cargo test`, like `tests/table_mutation.rs` for tables.
//!
//! Whatever the text: no panic, no abort (a stack overflow would end the test binary), a
//! refusal with a message of bounded length, and whatever succeeds finite — every
//! simulated value, every identified one — and loadable again when the tool wrote it.
//!
//! The test runs for `ADWI_ROBOT_MUTATION_SECONDS` (default 3) of wall time, from seed
//! `ADWI_ROBOT_MUTATION_SEED` (default 1); case `i` depends on the seed and `i` alone, so
//! `ADWI_ROBOT_MUTATION_CASE=i` replays one case. It prints the seed and the outcomes.

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use adwi_identify::calibrate::{identify, CalibrateOptions, Calibration};
use adwi_robot::testing::mutate;
use adwi_robot::{LinkNames, Robot};
use adwi_samples::{parse_samples, ColumnMap, SampleSet};
use adwi_simulate::{simulate, write_csv, Positions, SamplingPlan, Scenario};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// A message about any input stays readable: no unbounded list in it.
const MAX_MESSAGE_BYTES: usize = 4096;

fn shipped(path: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tables")
        .join(path);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// What a case starts from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Kind {
    /// A TOML robot file (MD-H or chain joints).
    Toml,
    /// A URDF file.
    Urdf,
    /// A TOML robot file naming a (mutated) URDF file.
    Naming,
    /// An error scenario, with the robot it was written for.
    Scenario,
}

struct Seeds {
    tomls: Vec<String>,
    urdfs: Vec<String>,
    /// Scenario text and the robot file it fits.
    scenarios: Vec<(String, String)>,
}

fn seeds() -> Seeds {
    let kr150 = shipped("kr150-2/robot.toml");
    let iiwa = shipped("iiwa14/robot.toml");
    Seeds {
        tomls: vec![
            kr150.clone(),
            shipped("ur5/robot.toml"),
            shipped("ur10/robot.toml"),
            iiwa.clone(),
        ],
        urdfs: vec![
            shipped("ur5/robot.urdf"),
            shipped("ur10/robot.urdf"),
            shipped("iiwa14/robot.urdf"),
        ],
        scenarios: vec![
            (shipped("kr150-2/scenario.toml"), kr150.clone()),
            (shipped("kr150-2/scenario_compliant.toml"), kr150),
            (shipped("iiwa14/scenario.toml"), iiwa),
        ],
    }
}

/// How a case ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Outcome {
    /// The robot file (or the scenario) was refused.
    Refused,
    /// Loaded, but the simulation was refused.
    SimulationRefused,
    /// Simulated, but the identification was refused.
    IdentificationRefused,
    /// Simulated, identified, written and loaded again.
    Calibrated,
}

/// An error and its sources, as the front ends print them.
fn chain(error: &dyn std::error::Error) -> String {
    let mut message = error.to_string();
    let mut source = error.source();
    while let Some(s) = source {
        message += &format!(": {s}");
        source = s.source();
    }
    message
}

fn bounded(what: &str, error: &dyn std::error::Error) -> Result<(), String> {
    let message = chain(error);
    if message.is_empty() || message.len() > MAX_MESSAGE_BYTES {
        return Err(format!(
            "{what}: a message of {} bytes: {}",
            message.len(),
            &message[..(0..=message.len().min(300))
                .rev()
                .find(|&i| message.is_char_boundary(i))
                .unwrap_or(0)]
        ));
    }
    Ok(())
}

fn finite(what: &str, values: impl IntoIterator<Item = f64>) -> Result<(), String> {
    match values.into_iter().find(|v| !v.is_finite()) {
        Some(v) => Err(format!("{what} is {v}")),
        None => Ok(()),
    }
}

/// A step of a case: its value, or the outcome that ends the case there (`Err` inside), or
/// a failure of the test (`Err` outside).
type Step<T> = Result<Result<T, Outcome>, String>;

/// One case: a seed file mutated one to three times, then every call down the line.
fn run_case(seeds: &Seeds, dir: &Path, seed: u64, case: u64) -> Result<(Kind, Outcome), String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(case);
    let kind = [Kind::Toml, Kind::Urdf, Kind::Naming, Kind::Scenario][rng.gen_range(0..4)];
    let case_dir = dir.join(format!("case{case}"));
    std::fs::create_dir_all(&case_dir).map_err(|e| e.to_string())?;
    let (robot_path, scenario_text) = write_mutated(seeds, &case_dir, kind, &mut rng);
    let outcome = follow(&robot_path, kind, scenario_text.as_deref(), case, &case_dir)?;
    Ok((kind, outcome))
}

/// Every call down the line on the case's files: load, simulate, identify, write back;
/// how far it went.
fn follow(
    robot_path: &Path,
    kind: Kind,
    scenario_text: Option<&str>,
    case: u64,
    case_dir: &Path,
) -> Result<Outcome, String> {
    let robot = match load(robot_path, kind)? {
        Ok(robot) => robot,
        Err(outcome) => return Ok(outcome),
    };
    let samples = match simulated_samples(&robot, scenario_text, case)? {
        Ok(samples) => samples,
        Err(outcome) => return Ok(outcome),
    };
    let options = CalibrateOptions {
        compliance: case % 2 == 0 && robot.gravity_model().is_some(),
        ..CalibrateOptions::default()
    };
    let c = match identify(&robot, &samples, &options) {
        Ok(c) => c,
        Err(e) => {
            bounded("identifying", &e)?;
            return Ok(Outcome::IdentificationRefused);
        }
    };
    written_back(&c, case_dir)?;
    Ok(Outcome::Calibrated)
}

/// The case's files: a seed of `kind` mutated one to three times, written to `case_dir`;
/// the robot file to load, and a mutated scenario's text.
fn write_mutated(
    seeds: &Seeds,
    case_dir: &Path,
    kind: Kind,
    rng: &mut ChaCha8Rng,
) -> (PathBuf, Option<String>) {
    let mutations = rng.gen_range(1..=3);
    let write = |name: &str, text: &str| -> PathBuf {
        let path = case_dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let mut scenario_text = None;
    let robot_path = match kind {
        Kind::Toml | Kind::Scenario => {
            let (mut text, scenario) = if kind == Kind::Toml {
                (
                    seeds.tomls[rng.gen_range(0..seeds.tomls.len())].clone(),
                    None,
                )
            } else {
                let (s, r) = &seeds.scenarios[rng.gen_range(0..seeds.scenarios.len())];
                (r.clone(), Some(s.clone()))
            };
            match scenario {
                Some(mut s) => {
                    for _ in 0..mutations {
                        mutate(&mut s, false, rng);
                    }
                    scenario_text = Some(s);
                }
                None => {
                    for _ in 0..mutations {
                        mutate(&mut text, false, rng);
                    }
                }
            }
            write("robot.toml", &text)
        }
        Kind::Urdf | Kind::Naming => {
            let mut text = seeds.urdfs[rng.gen_range(0..seeds.urdfs.len())].clone();
            for _ in 0..mutations {
                mutate(&mut text, true, rng);
            }
            let urdf = write("robot.urdf", &text);
            if kind == Kind::Naming {
                write(
                    "robot.toml",
                    "name = \"named\"\nurdf = \"robot.urdf\"\n[tool]\ntranslation_mm = [0.0, 0.0, 50.0]\n",
                )
            } else {
                urdf
            }
        }
    };
    (robot_path, scenario_text)
}

/// The robot of the case's file, which read the files it should.
fn load(robot_path: &Path, kind: Kind) -> Step<Robot> {
    match Robot::load_with_files(robot_path, &LinkNames::default()) {
        Ok((robot, files)) => {
            let expected = if kind == Kind::Naming { 2 } else { 1 };
            if files.len() != expected {
                return Err(format!("{} files read: {files:?}", files.len()));
            }
            Ok(Ok(robot))
        }
        Err(e) => {
            bounded("loading", &e)?;
            Ok(Err(Outcome::Refused))
        }
    }
}

/// 40 random poses of `robot` simulated under the scenario (perfect without one), every
/// value finite, written as CSV and read back as samples.
fn simulated_samples(robot: &Robot, scenario_text: Option<&str>, case: u64) -> Step<SampleSet> {
    let scenario = match scenario_text {
        Some(text) => match Scenario::from_toml_str(text) {
            Ok(s) => s,
            Err(e) => {
                bounded("the scenario", &e)?;
                return Ok(Err(Outcome::Refused));
            }
        },
        None => Scenario::perfect(robot.joint_count()),
    };
    let plan = SamplingPlan {
        positions: Positions::JointRandom {
            count: 40,
            ranges: None,
        },
        abc_deg: [0.0; 3],
        orientation_spread_deg: 0.0,
        config: None,
        seed: case,
    };
    let simulated = match simulate(robot, &scenario, &plan) {
        Ok(s) => s,
        Err(e) => {
            bounded("simulating", &e)?;
            return Ok(Err(Outcome::SimulationRefused));
        }
    };
    for s in &simulated {
        finite(
            "a simulated value",
            s.position_mm
                .iter()
                .chain(&s.abc_deg)
                .chain(&s.error_mm)
                .chain(&s.orientation_error_rad)
                .chain(&s.q_deg)
                .copied(),
        )?;
    }
    let mut csv = Vec::new();
    write_csv(&simulated, &[], &mut csv).map_err(|e| e.to_string())?;
    let samples = parse_samples(Path::new("simulated.csv"), &csv, &ColumnMap::default())
        .map_err(|e| format!("the simulated samples do not read back: {e}"))?;
    Ok(Ok(samples))
}

/// Every identified value finite, and the calibrated robot written as a robot file and as
/// URDF (into `case_dir`), each loading again.
fn written_back(c: &Calibration, case_dir: &Path) -> Result<(), String> {
    finite(
        "an identified value",
        c.deviations
            .iter()
            .copied()
            .chain(c.standard_errors.iter().flatten().copied())
            .chain([
                c.initial_position_rms_mm,
                c.position_rms_mm,
                c.residual_sigma_mm,
                c.orientation_rms_rad.unwrap_or(0.0),
            ]),
    )?;
    let calibrated = c.calibrated_robot();
    let toml = calibrated.to_toml_string(&["mutation test".into()]);
    Robot::from_toml_str(&toml).map_err(|e| {
        format!(
            "the calibrated robot file does not load: {}\n{toml}",
            chain(&e)
        )
    })?;
    let urdf = calibrated
        .to_urdf_string(&[])
        .map_err(|e| format!("the calibrated robot cannot be written as URDF: {e}"))?;
    let urdf_path = case_dir.join("calibrated.urdf");
    std::fs::write(&urdf_path, &urdf).unwrap();
    Robot::load_with(
        &urdf_path,
        &LinkNames {
            base_link: None,
            tip_link: Some(adwi_robot::urdf::TCP_LINK.into()),
            flange_link: None,
        },
    )
    .map_err(|e| format!("the calibrated URDF does not load: {}\n{urdf}", chain(&e)))?;
    Ok(())
}

#[test]
fn mutated_robot_files_and_scenarios_never_panic_nor_succeed_with_non_finite_values() {
    let seconds = env_or("ADWI_ROBOT_MUTATION_SECONDS", 3);
    let seed = env_or("ADWI_ROBOT_MUTATION_SEED", 1);
    let only: Option<u64> = std::env::var("ADWI_ROBOT_MUTATION_CASE")
        .ok()
        .and_then(|v| v.parse().ok());
    let seeds = seeds();
    let dir = tempfile::tempdir().unwrap();
    let budget = Duration::from_secs(seconds);
    let start = Instant::now();
    let mut counts: BTreeMap<(Kind, Outcome), u64> = BTreeMap::new();
    let mut case = only.unwrap_or(0);
    let mut cases = 0u64;
    while only.is_some() || start.elapsed() < budget {
        let rerun = format!("ADWI_ROBOT_MUTATION_SEED={seed} ADWI_ROBOT_MUTATION_CASE={case}");
        match catch_unwind(AssertUnwindSafe(|| {
            run_case(&seeds, dir.path(), seed, case)
        })) {
            Ok(Ok(outcome)) => *counts.entry(outcome).or_insert(0) += 1,
            Ok(Err(wrong)) => panic!("seed {seed}, case {case}: {wrong} (replay: {rerun})"),
            Err(_) => panic!("seed {seed}, case {case}: panicked (replay: {rerun})"),
        }
        let _ = std::fs::remove_dir_all(dir.path().join(format!("case{case}")));
        cases += 1;
        case += 1;
        if only.is_some() {
            break;
        }
    }
    eprintln!(
        "robot file mutation: seed {seed}, {cases} cases in {:.1} s: {counts:?}",
        start.elapsed().as_secs_f64()
    );
    if only.is_none() {
        // The mutations reach the range checks and the calibration alike.
        let count = |outcome| {
            counts
                .iter()
                .filter(|((_, o), _)| *o == outcome)
                .map(|(_, n)| n)
                .sum::<u64>()
        };
        assert!(count(Outcome::Refused) > 0, "{counts:?}");
        assert!(count(Outcome::Calibrated) > 0, "{counts:?}");
    }
}
