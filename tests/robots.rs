//! Robots beyond six MD-H joints through the real `tablec`: URDF robot files in
//! calibration and hybrid tables.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::{build_ur5_hybrid, repo, tablec, ur5_grid, UR5_MAP};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn ur5_random() -> PathBuf {
    repo("tables/ur5/measurements/3D_UR5_uncalibrated_random_cleaned.csv")
}

/// A hybrid table of a URDF robot: built from the URDF's chain, queried with six joint
/// values, refusing five.
#[test]
fn a_urdf_robot_makes_a_hybrid_table() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = repo("tables/ur5/robot.urdf");
    build_ur5_hybrid(dir.path(), urdf.to_str().unwrap(), &[], "h.tbl");
    // The grid's first sample, at its joints.
    let (x, y, z) = ("-430.328", "-6.274", "-98.637");
    let joints = "-22.9333,-43.7192,135.3978,-94.7403,55.4168,-5.5522";
    let o = tablec(&["query", "h.tbl", x, y, z, "--joints", joints], dir.path());
    let out = stdout(&o);
    assert!(
        out.contains("status") && out.contains("ok"),
        "{out}{}",
        stderr(&o)
    );
    let o = tablec(
        &[
            "query",
            "h.tbl",
            "400",
            "-100",
            "300",
            "--joints",
            "1,2,3,4,5",
        ],
        dir.path(),
    );
    assert!(!o.status.success(), "{}", stdout(&o));
}

/// `tablec eval --robot X.urdf`: the kinematic calibration of the URDF robot runs (the
/// URDF has no tool: the calibration identifies the tool offset), and the hybrid
/// method on its residuals improves on it.
#[test]
fn eval_takes_a_urdf_robot() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = repo("tables/ur5/robot.urdf");
    let o = tablec(
        &[
            "eval",
            ur5_grid().to_str().unwrap(),
            "--validation",
            ur5_random().to_str().unwrap(),
            "--columns",
            UR5_MAP,
            "--robot",
            urdf.to_str().unwrap(),
            "--methods",
            "kinematic,hybrid",
            "--cell",
            "30",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let kinematic = out
        .lines()
        .find(|l| l.starts_with("kinematic "))
        .unwrap_or_else(|| panic!("{out}"));
    let mean: f64 = kinematic
        .split_whitespace()
        .nth(4)
        .unwrap()
        .parse()
        .unwrap();
    // The MD-H robot file's calibration leaves 0.1005 mm (docs/evaluation.md); the URDF's
    // origin perturbations describe the same deviations.
    assert!(mean < 0.12, "{out}");
    let hybrid = out
        .lines()
        .find(|l| l.starts_with("hybrid "))
        .unwrap_or_else(|| panic!("{out}"));
    let hybrid_mean: f64 = hybrid.split_whitespace().nth(4).unwrap().parse().unwrap();
    assert!(hybrid_mean < mean, "{out}");
}

/// `tablec calibrate`: every parameter with its deviation and standard error or the reason
/// it was not identified, and the calibrated robot written as a robot file and as URDF,
/// both of which load again as robots of the same calibration.
#[test]
fn calibrate_reports_every_parameter_and_writes_the_calibrated_robot() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = repo("tables/ur5/robot.urdf");
    let grid = ur5_grid();
    let calibrate = |robot: &str, outputs: &[&str]| {
        let mut args = vec![
            "calibrate",
            grid.to_str().unwrap(),
            "--columns",
            UR5_MAP,
            "--robot",
            robot,
        ];
        args.extend_from_slice(outputs);
        let o = tablec(&args, dir.path());
        assert!(o.status.success(), "{}", stderr(&o));
        stdout(&o)
    };
    let out = calibrate(
        urdf.to_str().unwrap(),
        &["-o", "cal.toml", "--urdf", "cal.urdf"],
    );
    let after_mm = |out: &str| -> f64 {
        let line = out.lines().find(|l| l.starts_with("position RMS")).unwrap();
        let words: Vec<&str> = line.split_whitespace().collect();
        words[words.iter().position(|w| *w == "after;").unwrap() - 2]
            .parse()
            .unwrap()
    };
    assert!(after_mm(&out) < 0.13, "{out}");
    let identified: Vec<&str> = out
        .lines()
        .filter(|l| l.trim_end().ends_with(" identified"))
        .collect();
    assert!(identified.len() >= 15, "{out}");
    for line in &identified {
        // Names may hold a space ("base x"): the standard error is the word before the
        // unit.
        let words: Vec<&str> = line.split_whitespace().collect();
        let unit = words
            .iter()
            .position(|w| *w == "mm" || *w == "mrad")
            .unwrap();
        let se: f64 = words[unit - 1].parse().unwrap();
        assert!(se > 0.0 && se.is_finite(), "{line}");
    }
    assert!(
        out.contains("unidentifiable redundant with the identified parameters"),
        "{out}"
    );
    // The written robots load, and describe one robot: calibrating from either gives the
    // same residual.
    let from_toml = calibrate("cal.toml", &[]);
    let from_urdf = calibrate("cal.urdf", &[]);
    assert!(
        (after_mm(&from_toml) - after_mm(&from_urdf)).abs() < 1e-4,
        "{from_toml}\n{from_urdf}"
    );
    // Never over an input.
    let o = tablec(
        &[
            "calibrate",
            grid.to_str().unwrap(),
            "--columns",
            UR5_MAP,
            "--robot",
            "cal.toml",
            "-o",
            "cal.toml",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
}

/// `tablec calibrate` of the UR5 grid with `args` after the samples and their columns.
fn calibrate_ur5_grid(dir: &Path, args: &[&str]) -> Output {
    let grid = ur5_grid();
    let mut all = vec!["calibrate", grid.to_str().unwrap(), "--columns", UR5_MAP];
    all.extend_from_slice(args);
    tablec(&all, dir)
}

/// Builds a hybrid table of the UR5 grid with `robot`'s compliances identified into
/// `dir/c.tbl` and returns what `tablec inspect` prints of it.
fn inspect_compliant_hybrid(dir: &Path, robot: &str) -> String {
    build_ur5_hybrid(dir, robot, &["--compliance"], "c.tbl");
    stdout(&tablec(&["inspect", "c.tbl"], dir))
}

/// `tablec calibrate --compliance`: the UR5's joint compliances identified with its
/// geometry, reported in µrad/(N·m) and written to the calibrated robot file; a robot file
/// without link masses is refused with the reason.
#[test]
fn calibrate_identifies_gravity_compliance_given_link_masses() {
    let dir = tempfile::tempdir().unwrap();
    let robot = repo("tables/ur5/robot.toml");
    let o = calibrate_ur5_grid(
        dir.path(),
        &[
            "--robot",
            robot.to_str().unwrap(),
            "--compliance",
            "-o",
            "cal.toml",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let rows: Vec<&str> = out
        .lines()
        .filter(|l| l.trim_start().starts_with("compliance"))
        .collect();
    assert_eq!(rows.len(), 6, "{out}");
    for row in &rows {
        assert!(row.contains(" µrad/(N·m) "), "{row}");
    }
    // The shoulder (joint 2) carries the most torque: its compliance is identified, a
    // stiffness of a few 10⁴ N·m/rad.
    let shoulder = rows[1].split_whitespace().collect::<Vec<_>>();
    assert_eq!(shoulder[0], "compliance2");
    let value: f64 = shoulder[1].parse().unwrap();
    assert!((5.0..100.0).contains(&value), "{}", rows[1]);
    assert!(rows[1].trim_end().ends_with("identified"), "{}", rows[1]);
    let written = std::fs::read_to_string(dir.path().join("cal.toml")).unwrap();
    assert!(written.contains("compliance_urad_per_nm = "), "{written}");
    // A hybrid table stores them with its calibrated chain.
    let inspect = inspect_compliant_hybrid(dir.path(), robot.to_str().unwrap());
    let line = inspect
        .lines()
        .find(|l| l.starts_with("compliance "))
        .unwrap_or_else(|| panic!("{inspect}"));
    assert!(line.contains(&format!("{value:.4}")), "{line}\n{}", rows[1]);

    let kr150 = repo("tables/kr150-2");
    let o = tablec(
        &[
            "calibrate",
            kr150.join("samples.csv").to_str().unwrap(),
            "--robot",
            kr150.join("robot.toml").to_str().unwrap(),
            "--compliance",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(
        stderr(&o).contains("the robot file gives no link masses (mass_kg, com_mm per joint)"),
        "{}",
        stderr(&o)
    );
}

/// A robot file's `[payload]`: the compliances identified with it differ from those
/// without (5 kg at the flange loads every joint), the calibrated robot file keeps it, and
/// a hybrid table's calibrated chain carries it (`inspect` says so).
#[test]
fn a_payload_in_the_robot_file_loads_the_identified_compliance() {
    let dir = tempfile::tempdir().unwrap();
    let ur5 = std::fs::read_to_string(repo("tables/ur5/robot.toml")).unwrap();
    std::fs::write(
        dir.path().join("carrying.toml"),
        format!("{ur5}\n[payload]\nmass_kg = 5.0\ncom_mm = [0.0, 0.0, 60.0]\n"),
    )
    .unwrap();
    std::fs::write(dir.path().join("bare.toml"), &ur5).unwrap();
    let shoulder = |robot: &str| -> f64 {
        let out = format!("cal-{robot}");
        let o = calibrate_ur5_grid(dir.path(), &["--robot", robot, "--compliance", "-o", &out]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = stdout(&o);
        let row = out
            .lines()
            .find(|l| l.trim_start().starts_with("compliance2 "))
            .unwrap_or_else(|| panic!("{out}"));
        row.split_whitespace().nth(1).unwrap().parse().unwrap()
    };
    let (carrying, bare) = (shoulder("carrying.toml"), shoulder("bare.toml"));
    // The same deflections are explained by more torque: a smaller compliance.
    assert!(carrying < bare, "{carrying} against {bare}");
    let written = std::fs::read_to_string(dir.path().join("cal-carrying.toml")).unwrap();
    assert!(
        written.contains("\n[payload]\nmass_kg = 5.0\ncom_mm = [0.0, 0.0, 60.0"),
        "{written}"
    );
    let inspect = inspect_compliant_hybrid(dir.path(), "carrying.toml");
    // 60 mm beyond the flange is 26 mm beyond the calibrated TCP (34 mm beyond it).
    let line = inspect
        .lines()
        .find(|l| l.starts_with("load at flange  5 kg, centre of mass ("))
        .unwrap_or_else(|| panic!("{inspect}"));
    let centre = &line[line.find('(').unwrap() + 1..line.find(')').unwrap()];
    let z: f64 = centre.split(", ").nth(2).unwrap().parse().unwrap();
    assert!((25.0..28.0).contains(&z), "{line}");
}

/// A seven-joint robot end to end: simulated samples with seven joint columns, a hybrid
/// table of its calibrated chains, queries with seven joint values (six refused).
#[test]
fn a_seven_joint_robot_from_simulation_to_hybrid_queries() {
    let dir = tempfile::tempdir().unwrap();
    let robot = repo("tables/iiwa14/robot.toml");
    let scenario = repo("tables/iiwa14/scenario.toml");
    let o = tablec(
        &[
            "simulate",
            "--robot",
            robot.to_str().unwrap(),
            "--scenario",
            scenario.to_str().unwrap(),
            "--min",
            "400,-200,300",
            "--max",
            "600,200,600",
            "--random",
            "200",
            "--abc",
            "0,180,0",
            "-o",
            "s.csv",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.path().join("s.csv")).unwrap();
    let mut rows = text.lines().filter(|l| !l.starts_with('#'));
    let header = rows.next().unwrap();
    assert!(header.ends_with(",j1,j2,j3,j4,j5,j6,j7"), "{header}");
    let first: Vec<&str> = rows.next().unwrap().split(',').collect();
    let o = tablec(
        &[
            "build",
            "-q",
            "s.csv",
            "--robot",
            robot.to_str().unwrap(),
            "--hybrid",
            "-o",
            "t.tbl",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let joints = first[12..19].join(",");
    let six = first[12..18].join(",");
    let query = |joints: &str, exact: bool| {
        let mut args = vec![
            "query", "t.tbl", first[0], first[1], first[2], "--joints", joints,
        ];
        if exact {
            args.push("--exact");
        }
        tablec(&args, dir.path())
    };
    for exact in [false, true] {
        let o = query(&joints, exact);
        assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
        // The sample's own pose: the correction is its measured error to within the
        // residual interpolation's smoothing (tens of µm).
        let error = crate::common::printed_error(&stdout(&o));
        for a in 0..3 {
            let measured: f64 = first[6 + a].parse().unwrap();
            assert!((error[a] - measured).abs() < 0.05, "{error:?} vs {first:?}");
        }
    }
    // Six joint values for a seven-joint robot: a usage error.
    let o = query(&six, false);
    assert_eq!(o.status.code(), Some(2), "{}", stdout(&o));
    assert!(stderr(&o).contains("7 joint"), "{}", stderr(&o));
}

/// An arm on a linear track, as a chain robot file: the track's joint is prismatic, mm.
const TRACK_ROBOT: &str = r#"name = "arm on a track"
[tool]
translation_mm = [0.0, 0.0, 100.0]
[[joints]]
name = "track"
type = "prismatic"
axis = [1.0, 0.0, 0.0]
limits_mm = [0.0, 3000.0]
[[joints]]
name = "a1"
xyz_mm = [0.0, 0.0, 400.0]
limits_deg = [-170.0, 170.0]
[[joints]]
name = "a2"
xyz_mm = [150.0, 0.0, 300.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-120.0, 60.0]
[[joints]]
name = "a3"
xyz_mm = [0.0, 0.0, 600.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-110.0, 150.0]
[[joints]]
name = "a4"
xyz_mm = [500.0, 0.0, 100.0]
axis = [1.0, 0.0, 0.0]
limits_deg = [-180.0, 180.0]
[[joints]]
name = "a5"
axis = [0.0, 1.0, 0.0]
limits_deg = [-120.0, 120.0]
[[joints]]
name = "a6"
xyz_mm = [100.0, 0.0, 0.0]
axis = [1.0, 0.0, 0.0]
limits_deg = [-350.0, 350.0]
"#;

/// A track's position is a length wherever joint values are read: simulated samples, the
/// hybrid table built from them, `tablec query --targets` and `--joints`, and a CSV
/// program's `j` columns, read and written back, all in mm (a track at 1500 mm was read
/// as 1500 degrees by the query and the program, and its targets refused or answered at
/// another place on the track).
#[test]
fn a_track_is_read_in_mm_by_the_query_and_the_programs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let track = [
        (0.0, 2000.0),
        (-60.0, 60.0),
        (-60.0, 10.0),
        (-10.0, 80.0),
        (-90.0, 90.0),
        (30.0, 90.0),
        (-90.0, 90.0),
    ];
    simulated_table(d, TRACK_ROBOT, &track, 0, [250, 40]);
    let o = tablec(&["query", "t.tbl", "--targets", "v.csv", "-o", "q.csv"], d);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let rows = |file: &str| -> Vec<Vec<String>> {
        std::fs::read_to_string(d.join(file))
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with('#'))
            .map(|l| l.split(',').map(str::to_owned).collect())
            .collect()
    };
    let (validation, answers) = (rows("v.csv"), rows("q.csv"));
    let column =
        |table: &[Vec<String>], name: &str| table[0].iter().position(|c| c == name).unwrap();
    let status = column(&answers, "status");
    let mut worst: f64 = 0.0;
    for (v, a) in validation[1..].iter().zip(&answers[1..]) {
        assert_eq!(a[status], "ok", "{a:?}");
        let miss = ["x", "y", "z"]
            .iter()
            .map(|k| {
                let predicted: f64 = a[column(&answers, &format!("pred_d{k}"))].parse().unwrap();
                let measured: f64 = v[column(&validation, &format!("d{k}"))].parse().unwrap();
                (predicted - measured).powi(2)
            })
            .sum::<f64>()
            .sqrt();
        worst = worst.max(miss);
    }
    // The measured error is 0.3-1 mm; the table predicts it to its noise.
    assert!(worst < 0.1, "worst {worst} mm");
    // `eval --table` reads the held-out poses' track in mm too: every pose predicted.
    let o = tablec(&["eval", "--table", "t.tbl", "--validation", "v.csv"], d);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let table_row: Vec<String> = stdout(&o)
        .lines()
        .find(|l| l.starts_with("table "))
        .unwrap()
        .split_whitespace()
        .take(3)
        .map(str::to_owned)
        .collect();
    assert_eq!(table_row, ["table", "40", "0"], "{}", stdout(&o));
    // One target with --joints: the same answer as its row's.
    let first = &validation[1];
    let joints = first[column(&validation, "j1")..].join(",");
    let o = tablec(
        &[
            "query", "t.tbl", &first[0], &first[1], &first[2], "--joints", &joints,
        ],
        d,
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let error = crate::common::printed_error(&stdout(&o));
    for (a, k) in ["x", "y", "z"].iter().enumerate() {
        let row: f64 = answers[1][column(&answers, &format!("pred_d{k}"))]
            .parse()
            .unwrap();
        assert!(
            (error[a] - row).abs() < 1e-5,
            "{error:?} vs {:?}",
            answers[1]
        );
    }
    // A CSV program of those poses with their joints: every target corrected, the track
    // written back in mm beside its given value.
    let program: String = std::iter::once("x,y,z,a,b,c,j1,j2,j3,j4,j5,j6,j7\n".to_owned())
        .chain(validation[1..21].iter().map(|v| {
            let mut fields: Vec<&str> = ["x", "y", "z", "a", "b", "c"]
                .iter()
                .map(|k| v[column(&validation, k)].as_str())
                .collect();
            fields.extend(v[column(&validation, "j1")..].iter().map(String::as_str));
            fields.join(",") + "\n"
        }))
        .collect();
    std::fs::write(d.join("p.csv"), &program).unwrap();
    let o = tablec(
        &[
            "compensate",
            "t.tbl",
            "p.csv",
            "-o",
            "pc.csv",
            "--robot",
            "robot.toml",
            // The redundant track lets a millimetre's correction turn a joint by a few
            // degrees near a singular posture; the bound is not what is tested here.
            "--max-joint-change-deg",
            "10",
        ],
        d,
    );
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(
        stdout(&o).contains("20 of 20 targets corrected"),
        "{}",
        stdout(&o)
    );
    let (given, written) = (rows("p.csv"), rows("pc.csv"));
    for (g, w) in given[1..].iter().zip(&written[1..]) {
        let (g, w): (f64, f64) = (g[6].parse().unwrap(), w[6].parse().unwrap());
        assert!(
            (g - w).abs() < 2.0 && g > 0.0,
            "track {g} mm written as {w}"
        );
    }
}

/// A SCARA, as a chain robot file: three turns about the vertical and a stroke down.
const SCARA: &str = r#"name = "SCARA"
[tool]
translation_mm = [0.0, 0.0, -50.0]
[[joints]]
xyz_mm = [0.0, 0.0, 400.0]
limits_deg = [-130.0, 130.0]
[[joints]]
xyz_mm = [325.0, 0.0, 0.0]
limits_deg = [-145.0, 145.0]
[[joints]]
type = "prismatic"
xyz_mm = [275.0, 0.0, 0.0]
axis = [0.0, 0.0, -1.0]
limits_mm = [0.0, 200.0]
[[joints]]
axis = [0.0, 0.0, 1.0]
limits_deg = [-360.0, 360.0]
"#;

/// A five-axis arm: a base turn, three parallel pitch joints, a wrist roll.
const FIVE_AXES: &str = r#"name = "five axes"
[tool]
translation_mm = [0.0, 0.0, 80.0]
[[joints]]
xyz_mm = [0.0, 0.0, 300.0]
limits_deg = [-160.0, 160.0]
[[joints]]
axis = [0.0, 1.0, 0.0]
limits_deg = [-90.0, 90.0]
[[joints]]
xyz_mm = [0.0, 0.0, 250.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-10.0, 150.0]
[[joints]]
xyz_mm = [0.0, 0.0, 160.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-110.0, 110.0]
[[joints]]
xyz_mm = [0.0, 0.0, 70.0]
axis = [0.0, 0.0, 1.0]
limits_deg = [-200.0, 200.0]
"#;

/// Simulated samples (`s.csv`) and held-out poses (`v.csv`), `counts` of each, of `robot`
/// (a chain file whose joint `prismatic` slides; `usize::MAX`: none) at joint values drawn
/// in `ranges` (degrees; mm for the prismatic joint), each joint's origin and offset
/// deviated, and the hybrid table of the samples (`t.tbl`), in `d`; the held-out poses
/// lie a twentieth of each range inside it.
fn simulated_table(
    d: &Path,
    robot: &str,
    ranges: &[(f64, f64)],
    prismatic: usize,
    counts: [usize; 2],
) {
    std::fs::write(d.join("robot.toml"), robot).unwrap();
    let mut scenario = String::new();
    for i in 0..ranges.len() {
        let s = [0.05, 0.12, -0.08, 0.03, -0.02][i % 5];
        let offset = if i == prismatic {
            "mm = 0.2"
        } else {
            "deg = 0.015"
        };
        scenario.push_str(&format!(
            "[[joints]]\ndelta_xyz_mm = [{s}, 0.04, -0.03]\ndelta_rpy_deg = [0.003, -0.002, 0.0]\ndelta_offset_{offset}\n"
        ));
    }
    std::fs::write(d.join("scenario.toml"), scenario).unwrap();
    let mut rng = crate::common::SplitMix(3);
    let names: Vec<String> = (1..=ranges.len()).map(|i| format!("j{i}")).collect();
    // The held-out poses inside the samples' ranges by a twentieth: within their evidence.
    for (name, count, inset) in [
        ("poses.csv", counts[0], 0.0),
        ("val_poses.csv", counts[1], 0.05),
    ] {
        let mut text = names.join(",") + "\n";
        for _ in 0..count {
            let row: Vec<String> = ranges
                .iter()
                .map(|&(lo, hi)| {
                    let margin = inset * (hi - lo);
                    format!("{:.3}", rng.uniform(lo + margin, hi - margin))
                })
                .collect();
            text += &(row.join(",") + "\n");
        }
        std::fs::write(d.join(name), text).unwrap();
    }
    for (poses, out) in [("poses.csv", "s.csv"), ("val_poses.csv", "v.csv")] {
        let args = [
            "simulate",
            "--robot",
            "robot.toml",
            "--scenario",
            "scenario.toml",
        ];
        let o = tablec(&[&args[..], &["--poses", poses, "-o", out]].concat(), d);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let o = tablec(
        &[
            "build",
            "-q",
            "s.csv",
            "--robot",
            "robot.toml",
            "-o",
            "t.tbl",
        ],
        d,
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A SCARA cannot tilt its tool, a five-axis arm cannot take every orientation at every
/// position: a hybrid table's correction turns the tool by its orientation error, so every
/// command was `ik_failed`. Now the command reaches the position first and the
/// orientation as near as the joints allow, and its report line says how much of the turn
/// is left uncorrected.
#[test]
fn a_robot_of_fewer_than_six_joints_is_corrected_in_position_and_says_the_turn_left() {
    let scara = [
        (-120.0, 120.0),
        (-140.0, 140.0),
        (0.0, 200.0),
        (-180.0, 180.0),
    ];
    let five = [
        (-120.0, 120.0),
        (-30.0, 60.0),
        (20.0, 120.0),
        (-80.0, 80.0),
        (-180.0, 180.0),
    ];
    for (robot, ranges, prismatic) in [(SCARA, &scara[..], 2), (FIVE_AXES, &five[..], usize::MAX)] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        simulated_table(d, robot, ranges, prismatic, [300, 20]);
        let validation: Vec<Vec<String>> = std::fs::read_to_string(d.join("v.csv"))
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with('#'))
            .map(|l| l.split(',').map(str::to_owned).collect())
            .collect();
        let column = |name: &str| validation[0].iter().position(|c| c == name).unwrap();
        // The held-out poses as a program: x,y,z,a,b,c and the joints.
        let joints = (1..=ranges.len()).map(|i| format!("j{i}"));
        let keep: Vec<usize> = ["x", "y", "z", "a", "b", "c"]
            .map(str::to_owned)
            .into_iter()
            .chain(joints)
            .map(|c| column(&c))
            .collect();
        let program: String = validation
            .iter()
            .map(|row| {
                keep.iter()
                    .map(|&k| row[k].as_str())
                    .collect::<Vec<_>>()
                    .join(",")
                    + "\n"
            })
            .collect();
        std::fs::write(d.join("p.csv"), program).unwrap();
        let args = [
            "compensate",
            "t.tbl",
            "p.csv",
            "-o",
            "pc.csv",
            "--robot",
            "robot.toml",
        ];
        let o = tablec(&[&args[..], &["--report", "r.csv"]].concat(), d);
        assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
        assert!(
            stdout(&o).contains("20 of 20 targets corrected"),
            "{}",
            stdout(&o)
        );
        let left = format!(
            "beyond the {} joints' reach, left uncorrected",
            ranges.len()
        );
        assert!(stdout(&o).contains(&left), "{}", stdout(&o));
        // Each command's position correction is the pose's simulated error, to the
        // table's accuracy (a few µm here).
        let mut report = csv::Reader::from_path(d.join("r.csv")).unwrap();
        let header = report.headers().unwrap().clone();
        let at = |name: &str| header.iter().position(|c| c == name).unwrap();
        let mut worst: f64 = 0.0;
        for (row, line) in validation[1..].iter().zip(report.records()) {
            let line = line.unwrap();
            let miss = ["x", "y", "z"]
                .iter()
                .map(|k| {
                    let command: f64 = line[at(&format!("command_{k}"))].parse().unwrap();
                    let point: f64 = line[at(&format!("point_{k}"))].parse().unwrap();
                    let error: f64 = row[column(&format!("d{k}"))].parse().unwrap();
                    (command - point + error).powi(2)
                })
                .sum::<f64>()
                .sqrt();
            worst = worst.max(miss);
        }
        assert!(worst < 0.03, "worst {worst} mm");
    }
}
