//! `--measured-in`: the frame a sample file's measured poses are in. `base` (the default)
//! reads samples as they are; `tracker` reads measurements in a laser tracker's own frame,
//! registers them to the robot (adwi_robot::measured, the one reading the Python bindings
//! share) and hands every method the registered errors. The printing is the CLI's.

use std::path::Path;

use adwi_robot::measured::{Input, Registered};
use adwi_robot::register::{translation_and_rotation_deg, Refined, Registration};
use adwi_runtime::kinematics::Transform;
use adwi_samples::{ColumnMap, ReadOptions, SampleSet};

/// The frame the measured poses are in.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MeasuredIn {
    /// The robot's base frame: the file holds errors, or measured poses in the base frame.
    #[default]
    Base,
    /// A tracker's own frame: the file holds joints j1..jn and measured positions
    /// mx,my,mz (and, from a 6-D probe, a measured orientation).
    Tracker,
}

/// Reads a sample file as `frame` says: tracker-frame measurements registered to the robot
/// at `robot_path` (`--measured-in tracker`, which needs one), or samples as they are
/// (`adwi_robot::measured::read_samples`).
pub fn read_samples(
    frame: MeasuredIn,
    robot_path: Option<&Path>,
    links: &crate::RobotLinks,
    path: &Path,
    columns: &ColumnMap,
    read: &ReadOptions,
) -> anyhow::Result<(Option<Registered>, SampleSet)> {
    let tracker_robot = match (frame, robot_path) {
        (MeasuredIn::Tracker, Some(robot_path)) => Some(links.load(robot_path)?),
        _ => None,
    };
    Ok(adwi_robot::measured::read_samples(
        Input::File(path),
        columns,
        read,
        tracker_robot,
    )?)
}

/// Prints the registration: both transforms and the rigid fit's residuals.
pub fn print_registration(registered: &Registered) {
    let r = &registered.registration;
    println!(
        "registration   {} rows in the tracker frame, {}, rigid fit of the nominal robot \
         ({} iterations)",
        r.rows,
        if r.orientation {
            "6-D (positions and orientations)"
        } else {
            "positions only (probe rotation kept from the robot file)"
        },
        r.iterations
    );
    print_fit("fit residuals", &r.fit());
}

/// Prints both transforms as an identification of the registered samples refined them
/// ([`Registration::refined`](adwi_robot::register::Registration::refined)), with the
/// identified model's residuals.
pub fn print_refined(refined: &Refined) {
    println!("refined        by the identification's base and tool parameters:");
    print_fit("residuals", refined);
}

/// Prints a validation set's own registration
/// ([`adwi_robot::measured::Registered::samples_registered_apart`]):
/// its tracker-to-base transform and the calibrated model's residuals.
pub fn print_validation_registration(r: &Registration) {
    println!(
        "validation     registered apart ({} rows): the robot's frame in the moved tracker's, \
         fitted to the calibrated model's TCP positions; the probe is the samples'",
        r.rows
    );
    print_fit("fit residuals", &r.fit());
}

/// Both transforms, then the residuals they leave on a line of its own called `residuals`.
fn print_fit(residuals: &str, fit: &Refined) {
    print_transforms(&fit.base_in_tracker, &fit.probe);
    print_residuals(
        residuals,
        fit.position_rms_mm,
        fit.position_max_mm,
        fit.orientation_rms_rad.zip(fit.orientation_max_rad),
    );
}

fn print_transforms(base_in_tracker: &Transform, probe: &Transform) {
    for (name, t) in [
        ("base in tracker", base_in_tracker),
        ("probe on flange", probe),
    ] {
        let (p, r) = translation_and_rotation_deg(t);
        let angle = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        println!(
            "  {name}  translation ({:.4}, {:.4}, {:.4}) mm, rotation vector ({:.5}, {:.5}, \
             {:.5})° ({angle:.5}°)",
            p[0], p[1], p[2], r[0], r[1], r[2]
        );
    }
}

fn print_residuals(name: &str, rms_mm: f64, max_mm: f64, orientation: Option<(f64, f64)>) {
    let orientation = orientation.map_or(String::new(), |(rms, max)| {
        format!(
            "; orientation RMS {:.4} mrad, max {:.4} mrad",
            rms * 1e3,
            max * 1e3
        )
    });
    println!("  {name:<15}  position RMS {rms_mm:.4} mm, max {max_mm:.4} mm{orientation}");
}
