//! `--measured-in`: the frame a sample file's measured poses are in. `base` (the default)
//! reads samples as they are; `tracker` reads measurements in a laser tracker's own frame,
//! registers them to the robot (adwi_robot::register) and hands every method the
//! registered errors.

use std::path::Path;

use adwi_compile::samples::{read_measurements, ColumnMap, ReadOptions, SampleSet};
use adwi_robot::calibrate::Calibration;
use adwi_robot::register::{
    register, register_moved, translation_and_rotation_deg, Refined, RegisterOptions, Registration,
};
use adwi_robot::Robot;
use adwi_runtime::kinematics::Transform;
use anyhow::Context;

/// The frame the measured poses are given in.
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
/// at `robot_path` (`--measured-in tracker`, which needs one), or samples as they are.
pub fn read_samples(
    frame: MeasuredIn,
    robot_path: Option<&Path>,
    links: &crate::RobotLinks,
    path: &Path,
    columns: &ColumnMap,
    read: &ReadOptions,
) -> anyhow::Result<(Option<Registered>, SampleSet)> {
    match (frame, robot_path) {
        (MeasuredIn::Tracker, Some(robot_path)) => {
            let robot = links.load(robot_path)?;
            let (registered, samples) = Registered::read(path, columns, read, robot)?;
            Ok((Some(registered), samples))
        }
        _ => Ok((
            None,
            adwi_compile::samples::read_samples_with(path, columns, read)?,
        )),
    }
}

/// Tracker-frame measurements registered to a robot.
pub struct Registered {
    /// The registration.
    pub registration: Registration,
    /// The robot with the registered probe as its tool.
    pub robot: Robot,
    /// The robot as its file describes it.
    pub file_robot: Robot,
}

impl Registered {
    /// Reads tracker-frame measurements and registers them to `robot`: the registration
    /// and the registered base-frame samples.
    pub fn read(
        path: &Path,
        columns: &ColumnMap,
        read: &ReadOptions,
        robot: Robot,
    ) -> anyhow::Result<(Registered, SampleSet)> {
        let measurements = read_measurements(path, columns, read)?;
        let registration = register(&robot, &measurements, &RegisterOptions::default())
            .with_context(|| format!("cannot register {}", path.display()))?;
        let registered = Registered {
            robot: registration.robot(&robot)?,
            registration,
            file_robot: robot,
        };
        let samples = registered.samples(path, columns, read)?;
        Ok((registered, samples))
    }

    /// Reads more tracker-frame measurements (same tracker frame, same probe) as samples
    /// through this registration.
    pub fn samples(
        &self,
        path: &Path,
        columns: &ColumnMap,
        read: &ReadOptions,
    ) -> anyhow::Result<SampleSet> {
        let measurements = read_measurements(path, columns, read)?;
        self.registration
            .to_samples(&self.file_robot, &measurements)
            .with_context(|| format!("cannot register {}", path.display()))
    }

    /// Reads tracker-frame measurements taken after the tracker moved (another series) as
    /// samples: the robot's frame in the new tracker frame fitted to the TCP positions
    /// `calibration` (made from this registration's samples) predicts, the probe kept
    /// (`adwi_robot::register::register_moved`). Returns that registration with the
    /// samples.
    pub fn samples_registered_apart(
        &self,
        calibration: &Calibration,
        path: &Path,
        columns: &ColumnMap,
        read: &ReadOptions,
    ) -> anyhow::Result<(Registration, SampleSet)> {
        let measurements = read_measurements(path, columns, read)?;
        let registration = register_moved(
            &self.registration,
            calibration.calibrated_robot(),
            &measurements,
        )
        .with_context(|| format!("cannot register {}", path.display()))?;
        let samples = registration
            .to_samples(&self.file_robot, &measurements)
            .with_context(|| format!("cannot register {}", path.display()))?;
        Ok((registration, samples))
    }

    /// Prints the registration: both transforms and the rigid fit's residuals.
    pub fn print(&self) {
        let r = &self.registration;
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
        print_transforms(&r.base_in_tracker, &r.probe);
        print_residuals(
            "fit residuals",
            r.position_rms_mm,
            r.position_max_mm,
            r.orientation_rms_rad.zip(r.orientation_max_rad),
        );
    }

    /// Prints both transforms as `calibration` (identified from this registration's
    /// samples) refined them, with the identified model's residuals.
    pub fn print_refined(&self, calibration: &Calibration, samples: &SampleSet) {
        let refined: Refined = self.registration.refined(calibration, samples);
        println!("refined        by the identification's base and tool parameters:");
        print_transforms(&refined.base_in_tracker, &refined.probe);
        print_residuals(
            "residuals",
            refined.position_rms_mm,
            refined.position_max_mm,
            refined.orientation_rms_rad.zip(refined.orientation_max_rad),
        );
    }
}

/// Prints a validation set's own registration ([`Registered::samples_registered_apart`]):
/// its tracker-to-base transform and the calibrated model's residuals.
pub fn print_validation_registration(r: &Registration) {
    println!(
        "validation     registered apart ({} rows): the robot's frame in the moved tracker's, \
         fitted to the calibrated model's TCP positions; the probe is the samples'",
        r.rows
    );
    print_transforms(&r.base_in_tracker, &r.probe);
    print_residuals(
        "fit residuals",
        r.position_rms_mm,
        r.position_max_mm,
        r.orientation_rms_rad.zip(r.orientation_max_rad),
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
