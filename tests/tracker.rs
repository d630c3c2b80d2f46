//! `--measured-in tracker` through the real `tablec`: simulated measurements of a UR10 in a
//! far, turned tracker frame through an unknown probe, and the shipped UR10 series C.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Output;

use adwi_robot::error_model::{apply_deviations, deviations_from_vector};
use adwi_robot::model::{rotation_of, transform_from_parts};
use adwi_robot::{Geometry, Robot};
use adwi_runtime::kinematics::Transform;
use adwi_samples::pose::{kuka_abc_deg_from_rotation, rotation_from_vector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{repo, tablec};

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A tracker 2 m and more from the robot, turned 120° about a skew axis.
fn tracker() -> Transform {
    let axis = nalgebra::Vector3::new(1.0, 2.0, 3.0).normalize() * 120f64.to_radians();
    transform_from_parts([2000.0, -1500.0, 800.0], &rotation_from_vector(axis.into()))
}

/// A probe off the flange axis, turned 30°.
fn probe() -> Transform {
    let axis = nalgebra::Vector3::new(-1.0, 0.5, 2.0).normalize() * 30f64.to_radians();
    transform_from_parts([30.0, -20.0, 150.0], &rotation_from_vector(axis.into()))
}

/// Writes `tracker.csv`: the poses of the UR10 with `deviations` (MD-H vector) and the
/// probe, measured in the tracker frame, KUKA A, B, C angles, joints in degrees.
fn write_tracker_csv(dir: &Path, deviations: &[f64]) {
    write_series(dir, "tracker.csv", deviations, &tracker(), 3);
}

/// Writes the file `name`: 300 random poses (seed `seed`) of the UR10 with `deviations`
/// and the probe, measured from a tracker at `tracker`.
fn write_series(dir: &Path, name: &str, deviations: &[f64], tracker: &Transform, seed: u64) {
    let robot = Robot::load(repo("tables/ur10/robot.toml")).unwrap();
    let Geometry::Mdh(rows) = robot.geometry().clone() else {
        unreachable!("the UR10 file is MD-H")
    };
    let geometry = Geometry::Mdh(apply_deviations(&rows, &deviations_from_vector(deviations)));
    let actual = robot
        .with_geometry("actual".into(), geometry, robot.base(), probe())
        .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut csv = String::from("j1,j2,j3,j4,j5,j6,mx,my,mz,ma,mb,mc\n");
    for _ in 0..300 {
        let q: Vec<f64> = (0..6).map(|_| rng.gen_range(-2.5..2.5)).collect();
        let pose = tracker.compose(&actual.tcp_transform(&q));
        let abc = kuka_abc_deg_from_rotation(&rotation_of(&pose));
        for v in &q {
            write!(csv, "{:.15},", v.to_degrees()).unwrap();
        }
        let p = pose.translation_mm;
        writeln!(
            csv,
            "{:.12},{:.12},{:.12},{:.15},{:.15},{:.15}",
            p[0], p[1], p[2], abc[0], abc[1], abc[2]
        )
        .unwrap();
    }
    std::fs::write(dir.join(name), csv).unwrap();
}

/// The line of `out` starting with `prefix` (after spaces).
fn line<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines()
        .find(|l| l.trim_start().starts_with(prefix))
        .unwrap_or_else(|| panic!("no line {prefix} in\n{out}"))
}

/// A perfect robot: the build prints the tracker and the probe as simulated, with no
/// residual.
#[test]
fn tracker_measurements_of_a_perfect_robot_register_exactly() {
    let dir = tempfile::tempdir().unwrap();
    write_tracker_csv(dir.path(), &[0.0; 30]);
    let robot = repo("tables/ur10/robot.toml");
    let o = tablec(
        &[
            "build",
            "tracker.csv",
            "--robot",
            robot.to_str().unwrap(),
            "--hybrid",
            "--measured-in",
            "tracker",
            "-o",
            "t.tbl",
        ],
        dir.path(),
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(line(&out, "registration").contains("300 rows in the tracker frame, 6-D"));
    assert!(
        line(&out, "base in tracker").contains("translation (2000.0000, -1500.0000, 800.0000) mm"),
        "{out}"
    );
    assert!(
        line(&out, "probe on flange").contains("translation (30.0000, -20.0000, 150.0000) mm"),
        "{out}"
    );
    assert!(
        line(&out, "probe on flange").contains("(30.00000°)"),
        "{out}"
    );
    assert!(
        line(&out, "base in tracker").contains("(120.00000°)"),
        "{out}"
    );
    assert!(
        line(&out, "fit residuals").contains(
            "position RMS 0.0000 mm, max 0.0000 mm; orientation RMS 0.0000 mrad, max 0.0000 mrad"
        ),
        "{out}"
    );
}

/// Kinematic errors: the rigid fit keeps them, the identification explains them all (the
/// kinematic method predicts every held-out point exactly).
#[test]
fn tracker_measurements_calibrate_like_base_frame_ones() {
    let dir = tempfile::tempdir().unwrap();
    let mut deviations = [0.0; 30];
    // Δa, Δd, Δα, Δθ of joints 2 to 5 (0.3 mm, 0.5 mrad).
    for joint in 1..5 {
        deviations[joint * 5] = 0.3;
        deviations[joint * 5 + 2] = -5e-4;
        deviations[joint * 5 + 3] = 5e-4;
    }
    write_tracker_csv(dir.path(), &deviations);
    let robot = repo("tables/ur10/robot.toml");
    let o = tablec(
        &[
            "eval",
            "tracker.csv",
            "--robot",
            robot.to_str().unwrap(),
            "--measured-in",
            "tracker",
            "--folds",
            "5",
            "--methods",
            "kinematic",
            // The errors are geometric: the terms' choice (`joint_terms.rs`) is not the
            // subject.
            "--harmonics",
            "0",
        ],
        dir.path(),
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let fit = line(&out, "fit residuals");
    assert!(!fit.contains("position RMS 0.0000"), "{out}");
    assert!(
        line(&line_after(&out, "refined"), "residuals").contains(
            "position RMS 0.0000 mm, max 0.0000 mm; orientation RMS 0.0000 mrad, max 0.0000 mrad"
        ),
        "{out}"
    );
    let kinematic: Vec<&str> = line(&out, "kinematic ").split_whitespace().collect();
    assert_eq!(
        &kinematic[..8],
        [
            "kinematic",
            "300",
            "0",
            "│",
            "0.0000",
            "0.0000",
            "0.0000",
            "0.0000"
        ],
        "{out}"
    );
}

/// The text of `out` from the line starting with `prefix` on.
fn line_after(out: &str, prefix: &str) -> String {
    let start = out
        .lines()
        .position(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("no line {prefix} in\n{out}"));
    out.lines().skip(start).collect::<Vec<_>>().join("\n")
}

/// `--measured-in tracker` needs a robot, and is refused for plain tables.
#[test]
fn measured_in_tracker_needs_a_robot() {
    let dir = tempfile::tempdir().unwrap();
    write_tracker_csv(dir.path(), &[0.0; 30]);
    let o = tablec(
        &[
            "build",
            "tracker.csv",
            "--measured-in",
            "tracker",
            "-o",
            "t.tbl",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o).1);
    let o = tablec(
        &[
            "eval",
            "tracker.csv",
            "--measured-in",
            "tracker",
            "--folds",
            "5",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o).1);
}

/// A validation series measured after the tracker moved: read through the samples'
/// registration its errors hold the move, far beyond any robot's, and it is refused as
/// samples the robot does not fit; registered apart (the probe kept), the calibration
/// predicts it as well as the samples themselves.
#[test]
fn a_validation_series_from_a_moved_tracker_is_registered_apart() {
    let dir = tempfile::tempdir().unwrap();
    let mut deviations = [0.0; 30];
    for joint in 1..5 {
        deviations[joint * 5] = 0.3;
        deviations[joint * 5 + 3] = 5e-4;
    }
    write_series(dir.path(), "train.csv", &deviations, &tracker(), 3);
    let moved = transform_from_parts([40.0, -25.0, 10.0], &rotation_from_vector([0.0, 0.0, 0.02]))
        .compose(&tracker());
    write_series(dir.path(), "moved.csv", &deviations, &moved, 4);
    let robot = repo("tables/ur10/robot.toml");
    let eval = |apart: bool| {
        let mut args = vec![
            "eval",
            "train.csv",
            "--validation",
            "moved.csv",
            "--robot",
            robot.to_str().unwrap(),
            "--measured-in",
            "tracker",
            "--methods",
            "kinematic",
        ];
        if apart {
            args.push("--register-validation-apart");
        }
        tablec(&args, dir.path())
    };
    let o = eval(false);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("moved.csv: registered to the robot file, the measured positions lie more")
            && err.contains("are the rows one tracker frame's"),
        "{err}"
    );
    let o = eval(true);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("validation     registered apart"), "{out}");
    let mean: f64 = line(&out, "kinematic ")
        .split_whitespace()
        .nth(4)
        .unwrap()
        .parse()
        .unwrap();
    assert!(mean < 1e-6, "{out}");
}

/// Two series of one robot measured from two tracker positions train one calibration:
/// each series is registered with its own tracker-to-base transform (printed) and the
/// probe they share, and the identification explains both as well as it explains one. The
/// same rows taken as one series (one transform for both) cannot be explained at all.
#[test]
fn series_from_two_tracker_positions_train_one_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let mut deviations = [0.0; 30];
    for joint in 1..5 {
        deviations[joint * 5] = 0.3;
        deviations[joint * 5 + 3] = 5e-4;
    }
    let moved = {
        let axis = nalgebra::Vector3::new(0.0, 0.0, 1.0) * 40f64.to_radians();
        transform_from_parts([-1000.0, 2500.0, 300.0], &rotation_from_vector(axis.into()))
    };
    write_series(dir.path(), "a.csv", &deviations, &tracker(), 3);
    write_series(dir.path(), "c.csv", &deviations, &moved, 4);
    let robot = repo("tables/ur10/robot.toml");
    let calibrate = |files: &[&str]| {
        let mut args = vec!["calibrate"];
        args.extend_from_slice(files);
        args.extend([
            "--robot",
            robot.to_str().unwrap(),
            "--measured-in",
            "tracker",
        ]);
        let o = tablec(&args, dir.path());
        let (out, err) = text(&o);
        assert!(o.status.success(), "{err}");
        out
    };
    let after = |out: &str| -> f64 {
        let l = line(out, "position RMS");
        l.split(", ")
            .nth(1)
            .unwrap()
            .split_whitespace()
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let both = calibrate(&["a.csv", "c.csv"]);
    assert!(
        line(&both, "series 2")
            .contains("registered to the robot identified from every series (300 rows)"),
        "{both}"
    );
    // The second series' tracker as simulated, in the frame of the first series'
    // calibration (its base deviation moves it by a fraction of a millimetre).
    let second = both[both.find("series 2").unwrap()..].to_string();
    let translation: Vec<f64> = line(&second, "base in tracker")
        .split('(')
        .nth(1)
        .unwrap()
        .split(')')
        .next()
        .unwrap()
        .split(", ")
        .map(|v| v.parse().unwrap())
        .collect();
    for (got, simulated) in translation.iter().zip([-1000.0, 2500.0, 300.0]) {
        assert!((got - simulated).abs() < 0.2, "{second}");
    }
    assert!(after(&both) < 1e-3, "{both}");
    // One file holding both series cannot be fitted with one transform.
    let a = std::fs::read_to_string(dir.path().join("a.csv")).unwrap();
    let c = std::fs::read_to_string(dir.path().join("c.csv")).unwrap();
    let merged = a + c.split_once('\n').unwrap().1;
    std::fs::write(dir.path().join("merged.csv"), merged).unwrap();
    let o = tablec(
        &[
            "calibrate",
            "merged.csv",
            "--robot",
            robot.to_str().unwrap(),
            "--measured-in",
            "tracker",
        ],
        dir.path(),
    );
    let (out, _) = text(&o);
    assert!(!o.status.success() || after(&out) > 100.0, "{out}");
}
