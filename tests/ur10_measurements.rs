//! The shipped UR10 laser-tracker measurements (`tables/ur10/measurements`): each file read
//! by `read_measurements` through the column mapping its README gives, with the row counts,
//! the joint count and one row's values as written; and the frames the README describes.
// The files write π/2 to five digits, and these tests quote them.
#![allow(clippy::approx_constant)]

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use adwi_samples::pose;
use adwi_samples::{read_measurements, ColumnMap, Measurements, ReadOptions};
use approx::assert_abs_diff_eq;
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

fn folder() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables/ur10/measurements")
}

/// The `--columns` line of the README, which reads every measurement file.
fn readme_columns() -> ColumnMap {
    let readme = std::fs::read_to_string(folder().join("README.md")).unwrap();
    let line = readme
        .lines()
        .find_map(|l| l.trim().strip_prefix("--columns "))
        .expect("a --columns line in the README");
    ColumnMap::parse(line.trim()).unwrap()
}

fn read(file: &str) -> Measurements {
    read_measurements(
        &folder().join(file),
        &readme_columns(),
        &ReadOptions::default(),
    )
    .unwrap()
}

fn about(axis: Vector3<f64>, angle_rad: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle_rad)
}

/// One row as the file writes it: Goal position (m) and roll, pitch, yaw (rad), the six
/// joints (rad), the measured position (mm) and rx, ry, rz (degrees).
struct Row {
    line: u64,
    goal_m: [f64; 3],
    goal_rpy_rad: [f64; 3],
    joints_rad: [f64; 6],
    measured_mm: [f64; 3],
    measured_deg: [f64; 3],
}

fn check_row(m: &Measurements, row: &Row) {
    let i = m.lines.iter().position(|&l| l == row.line).unwrap();
    assert_eq!(m.joints.row(i), row.joints_rad);
    let nominal = m.nominal_mm.as_ref().unwrap()[i];
    for (mm, m) in nominal.iter().zip(row.goal_m) {
        assert_abs_diff_eq!(*mm, m * 1000.0, epsilon = 1e-9);
    }
    assert_eq!(m.measured_mm[i], row.measured_mm);
    // Goal: extrinsic x-y-z, R = Rz(yaw)·Ry(pitch)·Rx(roll).
    let [roll, pitch, yaw] = row.goal_rpy_rad;
    let goal = about(Vector3::z(), yaw) * about(Vector3::y(), pitch) * about(Vector3::x(), roll);
    let read = &m.nominal_rotation.as_ref().unwrap()[i];
    assert_abs_diff_eq!(read.matrix(), goal.matrix(), epsilon = 1e-14);
    // Measured: intrinsic X-Y-Z, R = Rx(rx)·Ry(ry)·Rz(rz).
    let [rx, ry, rz] = row.measured_deg.map(f64::to_radians);
    let measured = about(Vector3::x(), rx) * about(Vector3::y(), ry) * about(Vector3::z(), rz);
    let read = &m.measured_rotation.as_ref().unwrap()[i];
    assert_abs_diff_eq!(read.matrix(), measured.matrix(), epsilon = 1e-14);
}

#[test]
fn series_a_grid_reads_with_its_values() {
    let m = read("Series_A/measurements_grid.csv");
    // 11,911 data rows (the last without a line end).
    assert_eq!(m.len(), 11_911);
    assert_eq!(m.joint_count(), 6);
    assert_eq!((m.lines[0], m.lines[m.len() - 1]), (2, 11_912));
    check_row(
        &m,
        &Row {
            line: 6000,
            goal_m: [1.0, 0.3, 0.5],
            goal_rpy_rad: [1.5708, 1.5708, 1.53589],
            joints_rad: [
                -2.58168,
                -2.13971,
                -1.47091,
                0.469209,
                0.975292,
                -0.00173504,
            ],
            measured_mm: [1668.2172, -1299.5568, -812.06595],
            measured_deg: [-90.469011, -57.702216, -91.04483],
        },
    );
}

#[test]
fn series_b_joint_configurations_read_with_their_values() {
    let m = read("Series_B/measurements_joint_configurations.csv");
    assert_eq!(m.len(), 1_495);
    assert_eq!(m.joint_count(), 6);
    // Scientific notation with decimal commas in the goal: -2,78E-05 rad.
    check_row(
        &m,
        &Row {
            line: 2,
            goal_m: [0.000121973, -0.365141, 1.4273],
            goal_rpy_rad: [1.56998, 1.57013, -2.78e-05],
            joints_rad: [-3.14159, -1.5708, 0.0, -1.5708, 0.0, 0.0],
            measured_mm: [383.76294, -3240.8734, 201.93157],
            measured_deg: [-90.179302, -20.118749, -90.169308],
        },
    );
}

#[test]
fn series_c_random_poses_read_with_their_values() {
    let m = read("Series_C/measurements_random_poses.csv");
    assert_eq!(m.len(), 2_773);
    assert_eq!(m.joint_count(), 6);
    check_row(
        &m,
        &Row {
            line: 2774,
            goal_m: [-0.0216848, -0.788696, 0.89897],
            goal_rpy_rad: [2.82986, 1.59081, 1.44463],
            joints_rad: [-4.53168, -3.00905, 1.49701, -1.61063, 1.57496, -0.0068329],
            measured_mm: [263.06373, -2831.6744, -327.93786],
            measured_deg: [-88.998312, -30.644696, -90.023213],
        },
    );
}

/// The flange of the UR10's nominal Denavit-Hartenberg model at joint angles `q`, mm.
fn ur10_flange(q: &[f64]) -> Isometry3<f64> {
    let d = [127.3, 0.0, 0.0, 163.941, 115.7, 92.2];
    let a = [0.0, -612.0, -572.3, 0.0, 0.0, 0.0];
    let alpha = [PI / 2.0, 0.0, 0.0, PI / 2.0, -PI / 2.0, 0.0];
    (0..6).fold(Isometry3::identity(), |t, i| {
        let joint = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), q[i]);
        let twist = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), alpha[i]);
        t * Isometry3::from_parts(Translation3::identity(), joint)
            * Isometry3::from_parts(Translation3::new(a[i], 0.0, d[i]), twist)
    })
}

/// What the README says of the frames, checked on every row of every file: the Goal pose
/// is the probe's, planned in the ROS `base_link` frame (the DH base turned 180° about z)
/// with the probe at the inverse of `Trafo_TM_F_init.txt` from the flange; and the measured
/// orientations are intrinsic X-Y-Z: the rotation between two rows' measured orientations
/// turns by the angle between their Goal orientations (the tracker's frame and the probe's
/// own frame change neither), to the robot's few milliradians.
#[test]
fn the_goal_is_the_probe_in_base_link_and_measured_angles_are_intrinsic_xyz() {
    let text = std::fs::read_to_string(folder().join("Series_A/Trafo_TM_F_init.txt")).unwrap();
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect();
    let rotation = Rotation3::from_matrix(&Matrix3::new(
        v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10],
    ));
    let probe_to_flange = Isometry3::from_parts(
        Translation3::new(v[3], v[7], v[11]),
        UnitQuaternion::from_rotation_matrix(&rotation),
    );
    let base_link = Isometry3::rotation(Vector3::z() * PI);
    let angle = |r: &Rotation3<f64>| Vector3::from(pose::rotation_vector(r)).norm();
    for file in [
        "Series_A/measurements_grid.csv",
        "Series_B/measurements_joint_configurations.csv",
        "Series_C/measurements_random_poses.csv",
    ] {
        let m = read(file);
        let goal_rotation = m.nominal_rotation.as_ref().unwrap();
        let measured_rotation = m.measured_rotation.as_ref().unwrap();
        let (mut worst_mm, mut worst_rad, mut worst_turn) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..m.len() {
            let probe = base_link * ur10_flange(m.joints.row(i)) * probe_to_flange.inverse();
            let goal = Vector3::from(m.nominal_mm.as_ref().unwrap()[i]);
            worst_mm = worst_mm.max((probe.translation.vector - goal).norm());
            let r = probe.rotation.to_rotation_matrix() * goal_rotation[i].inverse();
            worst_rad = worst_rad.max(angle(&r));
            if i > 0 {
                let measured = measured_rotation[i] * measured_rotation[i - 1].inverse();
                let commanded = goal_rotation[i] * goal_rotation[i - 1].inverse();
                worst_turn = worst_turn.max((angle(&measured) - angle(&commanded)).abs());
            }
        }
        // Joints written to 6 digits: within a millimetre and a few milliradians.
        assert!(worst_mm < 1.0, "{file}: goal {worst_mm} mm from the model");
        assert!(
            worst_rad < 3e-3,
            "{file}: goal {worst_rad} rad from the model"
        );
        assert!(
            worst_turn < 10e-3,
            "{file}: turns differ by {worst_turn} rad"
        );
    }
}
