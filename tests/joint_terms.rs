//! Joint-space terms end to end: a hybrid table whose model has them is format version 5,
//! opens, and answers with its model's terms from both tiers; the committed version-5
//! fixture (`tables/compat/v5/`) gives its recorded answers.

use std::path::{Path, PathBuf};

use adwi_runtime::format::{CONTENT_JOINT_TERMS, CONTENT_MODEL};
use adwi_runtime::{Status, Table};

use crate::common::UR5_MAP;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `tables/compat/v5/README.md`'s answers at the first three random UR5 poses: served
/// position error, exact position error (mm), orientation error (rad).
const V5_ANSWERS: [([f64; 3], [f64; 3], [f64; 3]); 3] = [
    (
        [-2.436734916, -0.390571989, -0.675120641],
        [-2.425876347, -0.410141247, -0.677008046],
        [0.010603301, 0.004822871, 0.001168579],
    ),
    (
        [-2.639977496, -0.070398894, -0.696099140],
        [-2.639653291, -0.041591150, -0.723128726],
        [0.010368814, 0.005758638, -0.000038137],
    ),
    (
        [-2.489707849, -0.245725413, -0.524019117],
        [-2.495394645, -0.242277981, -0.508036170],
        [0.008752342, 0.008916288, 0.002087621],
    ),
];

/// The version-5 fixture opens, carries joint-space terms (joints 1, 2, 4 and 5), and
/// gives its recorded answers from both tiers; its model part is the prepared model's
/// error with the terms, which differs from the chains' without them.
#[test]
fn the_version_5_table_opens_and_gives_its_recorded_answers() {
    let path = root().join("tables/compat/v5/ur5_hybrid_terms.tbl");
    // SAFETY: a committed fixture, not modified while the test runs.
    let table = unsafe { Table::open(&path) }.unwrap();
    let h = table.header();
    assert_eq!(h.version, 5);
    assert_ne!(h.content_flags & CONTENT_JOINT_TERMS, 0);
    assert_ne!(h.content_flags & CONTENT_MODEL, 0);
    let model = table.model().unwrap();
    let terms = model.joint_terms();
    assert!(!terms.is_none());
    let points = crate::common::ur5_random();
    let answers = crate::common::assert_recorded_ur5_answers(&table, &points, &V5_ANSWERS);
    for (i, (s, e)) in answers.into_iter().enumerate() {
        assert_eq!((s.status, e.status), (Status::Ok, Status::Ok), "pose {i}");
        let q = points.joints_rad(i).unwrap();
        // The query's model part is the prepared model's (with the terms) to the query
        // path's rounding, and the terms change it.
        let at = model.at(q).unwrap();
        let (position, _) = model.error(q).unwrap();
        let without =
            adwi_runtime::model::PreparedModel::new(*model.nominal(), *model.calibrated())
                .unwrap()
                .error(q)
                .unwrap()
                .0;
        let moved: f64 = (0..3)
            .map(|a| (position[a] - without[a]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            moved > 1e-3,
            "pose {i}: the terms move the model by {moved} mm"
        );
        for (query, exact) in at.position_mm.iter().zip(position) {
            assert!((query - exact).abs() < 1e-9, "pose {i}: {query} vs {exact}");
        }
    }
}

/// A hybrid table is version 6 with its joint record, with terms or without: its terms
/// zero without (`--harmonics 0`), not with `--harmonics 1`; the build prints the joint
/// angles its samples span.
#[test]
fn every_hybrid_table_is_version_6_its_terms_with_harmonics_alone() {
    let dir = std::env::temp_dir().join(format!("adwi-joint-terms-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let samples = root().join("tables/ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv");
    let robot = root().join("tables/ur5/robot.toml");
    let mut versions = Vec::new();
    for harmonics in ["0", "1"] {
        let out = dir.join(format!("h{harmonics}.tbl"));
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_tablec"))
            .args(["build", "--cell", "100", "--served-field", "method"])
            .args(["--posture", "off", "--harmonics", harmonics, "-o"])
            .arg(&out)
            .arg(&samples)
            .args(["--columns", UR5_MAP, "--robot"])
            .arg(&robot)
            .output()
            .unwrap();
        assert!(output.status.success());
        // The build says where its residual is served, as `inspect` does.
        let printed = String::from_utf8_lossy(&output.stdout);
        assert!(
            printed.contains("residual joints j1 [-24.4, 56.5], j2 [-105.0, -25.5]"),
            "{printed}"
        );
        let table = Table::from_vec(std::fs::read(&out).unwrap()).unwrap();
        versions.push((
            table.header().version,
            table.header().content_flags & CONTENT_JOINT_TERMS != 0,
            table.model().unwrap().joint_terms().is_none(),
        ));
    }
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(versions, [(6, true, true), (6, true, false)]);
}

/// Simulates 400 random KR150-2 poses (tool turned up to 30° about random axes, so every
/// joint moves) into `dir/NAME.csv` with the geometric scenario's errors, and with a
/// transmission error of one period per revolution (0.03°) on joint 2 when `gear`.
fn simulated_kr150(dir: &Path, name: &str, gear: bool) -> PathBuf {
    let geometric =
        std::fs::read_to_string(root().join("tables/kr150-2/scenario_geometric.toml")).unwrap();
    let a2 = "[[joints]] # A2 (parallel to A3: the twist about y is beta)\n";
    assert!(geometric.contains(a2));
    let scenario = if gear {
        geometric.replace(
            a2,
            &format!(
                "{a2}gear_amplitude_deg = 0.03\ngear_periods_per_rev = 1.0\ngear_phase_deg = 40.0\n"
            ),
        )
    } else {
        geometric
    };
    let scenario_path = dir.join(format!("{name}.toml"));
    std::fs::write(&scenario_path, scenario).unwrap();
    let csv = dir.join(format!("{name}.csv"));
    let robot = root().join("tables/kr150-2/robot.toml");
    let out = crate::common::tablec(
        &[
            "simulate",
            "--robot",
            robot.to_str().unwrap(),
            "--scenario",
            scenario_path.to_str().unwrap(),
            "--min",
            "1350,50,850",
            "--max",
            "2150,850,1650",
            "--abc",
            "0,90,0",
            "--orientation-spread",
            "30",
            "--random",
            "400",
            "--seed",
            "3",
            "-o",
            csv.to_str().unwrap(),
        ],
        dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    csv
}

/// The harmonic count `--harmonics auto`, the default, chooses, as its build reports it:
/// none where the errors are geometric, the first harmonic where joint 2 has a periodic transmission
/// error of one period per revolution, each count scored on the same 5 spatial blocks; and
/// the table it writes is the one of the count it chose, byte for byte (where it chooses
/// none, the `--harmonics 0` table; where it chooses the first harmonic, the
/// `--harmonics 1` table). One build per sample set checks both: the choice costs five
/// identifications for each count.
#[test]
fn the_choice_takes_harmonics_where_a_joint_has_a_periodic_error_and_builds_that_counts_table() {
    let dir = tempfile::tempdir().unwrap();
    let robot = root().join("tables/kr150-2/robot.toml");
    let mut means = Vec::new();
    for (gear, chosen) in [(false, "0"), (true, "1")] {
        let name = if gear { "gear" } else { "geometric" };
        let csv = simulated_kr150(dir.path(), name, gear);
        let mut tables = Vec::new();
        // `auto` is the default: the first build does not name it.
        for harmonics in ["auto", chosen] {
            let out = dir.path().join(format!("{name}-{harmonics}.tbl"));
            let mut args = vec![
                "build",
                csv.to_str().unwrap(),
                "--robot",
                robot.to_str().unwrap(),
                "--served-field",
                "method",
                "--posture",
                "off",
                "--residual-weight",
                "full",
                "-o",
                out.to_str().unwrap(),
            ];
            if harmonics != "auto" {
                args.extend(["--harmonics", harmonics]);
            }
            let o = crate::common::tablec(&args, dir.path());
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let text = String::from_utf8_lossy(&o.stdout).into_owned();
            // The choice is printed when made, the count chosen marked.
            assert_eq!(
                text.contains(&format!("  * harmonics {chosen}:")),
                harmonics == "auto",
                "{text}"
            );
            if harmonics == "auto" {
                means.push(harmonics_means(&text));
            }
            // The other choices were given: none is made.
            assert!(
                !text.contains("served field   chosen") && !text.contains("residual weight "),
                "{text}"
            );
            tables.push(std::fs::read(&out).unwrap());
        }
        assert!(
            tables[0] == tables[1],
            "{name}: auto is not --harmonics {chosen}"
        );
    }
    // With the periodic error, its terms lower the held-out mean by far more than the
    // noise; without, none lowers it.
    assert!(means[1][0] - means[1][1] > 0.005, "{means:?}");
    assert!(means[0][1] >= means[0][0] - 0.001, "{means:?}");
}

/// Each count's held-out mean (mm) from a build's report of its harmonic choice, in the
/// order printed, which must be the counts 0, 1 and 2 scored on 5 spatial blocks.
fn harmonics_means(report: &str) -> Vec<f64> {
    let mut lines = report.lines().skip_while(|l| !l.starts_with("harmonics "));
    let head = lines
        .next()
        .unwrap_or_else(|| panic!("no harmonic choice in:\n{report}"));
    assert!(
        head.contains("chosen by 5 spatial blocks, each predicted from the others"),
        "{head}"
    );
    let mut means = Vec::new();
    for (count, line) in lines.take(3).enumerate() {
        let rest = line[4..]
            .strip_prefix(&format!("harmonics {count}: "))
            .unwrap_or_else(|| panic!("count {count} not in {line:?}"));
        let mean = rest.split(" mm mean").next().unwrap();
        means.push(mean.parse().unwrap_or_else(|_| panic!("{line:?}")));
    }
    assert_eq!(means.len(), 3, "{report}");
    means
}
