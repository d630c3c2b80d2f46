//! Sample files whose measured poses are in a laser tracker's own frame, read as base-frame
//! samples: the measurements (joints `j1..jn`, measured `mx,my,mz` and optionally a
//! measured orientation) are registered to the robot ([`crate::register`]) and every
//! method then sees the registered errors. `tablec` (`--measured-in tracker`) and the
//! Python bindings (`measured_in="tracker"`) both read through here, so that they register
//! alike and word their errors alike.

use std::path::{Path, PathBuf};

use adwi_samples::{
    parse_measurements, parse_samples_with, read_measurements, read_samples_with, ColumnMap,
    Measurements, ReadError, ReadOptions, SampleSet,
};

use crate::calibrate::{identify, CalibrateError, CalibrateOptions, Calibration};
use crate::register::{
    register, register_moved, Refined, RegisterError, RegisterOptions, Registration,
};
use adwi_robot::{Robot, RobotError};

/// A sample file: on disk, or its CSV text in memory (a DataFrame's, say), named by `name`
/// in messages as the file would be.
#[derive(Debug, Clone, Copy)]
pub enum Input<'a> {
    /// A file.
    File(&'a Path),
    /// CSV text.
    Memory {
        /// What messages call it.
        name: &'a Path,
        /// The text.
        bytes: &'a [u8],
    },
}

impl Input<'_> {
    /// What messages call it.
    pub fn name(&self) -> &Path {
        match self {
            Input::File(path) => path,
            Input::Memory { name, .. } => name,
        }
    }

    /// Its rows as samples, as they are (base frame).
    ///
    /// # Errors
    ///
    /// As [`read_samples_with`].
    pub fn samples(&self, columns: &ColumnMap, read: &ReadOptions) -> Result<SampleSet, ReadError> {
        match self {
            Input::File(path) => read_samples_with(path, columns, read),
            Input::Memory { name, bytes } => parse_samples_with(name, bytes, columns, read),
        }
    }

    /// Its rows as raw measurements.
    ///
    /// # Errors
    ///
    /// As [`read_measurements`].
    pub fn measurements(
        &self,
        columns: &ColumnMap,
        read: &ReadOptions,
    ) -> Result<Measurements, ReadError> {
        match self {
            Input::File(path) => read_measurements(path, columns, read),
            Input::Memory { name, bytes } => parse_measurements(name, bytes, columns, read),
        }
    }
}

/// Why tracker-frame measurements cannot be read as samples.
#[derive(Debug, thiserror::Error)]
pub enum MeasuredError {
    /// The file cannot be read (with file, line and column).
    #[error(transparent)]
    Read(#[from] ReadError),
    /// The measurements cannot be registered to the robot.
    #[error("cannot register {}", path.display())]
    Register {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: RegisterError,
    },
    /// The registered probe does not make a robot.
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// The registered samples cannot be identified (for a validation series registered
    /// apart, or for the refined transforms).
    #[error(transparent)]
    Identify(#[from] CalibrateError),
}

impl MeasuredError {
    fn register(input: &Input<'_>) -> impl FnOnce(RegisterError) -> MeasuredError {
        let path = input.name().to_path_buf();
        move |source| MeasuredError::Register { path, source }
    }
}

/// Reads `input` as samples: registered to `tracker_robot` when given (the file's poses
/// are in a tracker's frame), otherwise as they are. The caller decides the frame, and
/// refuses a tracker frame without a robot in its own words.
///
/// # Errors
///
/// As [`Registered::read`], or the file's reading error.
pub fn read_samples(
    input: Input<'_>,
    columns: &ColumnMap,
    read: &ReadOptions,
    tracker_robot: Option<Robot>,
) -> Result<(Option<Registered>, SampleSet), MeasuredError> {
    match tracker_robot {
        Some(robot) => {
            let (registered, samples) = Registered::read(input, columns, read, robot)?;
            Ok((Some(registered), samples))
        }
        None => Ok((None, input.samples(columns, read)?)),
    }
}

/// Reads a validation series into the frame of the `samples` that `registered` (when they
/// were registered) was read with: as it is without a registration; through that
/// registration (the same tracker frame); or, with `apart`, registered on its own to the
/// TCP positions of the identification of `samples` by those options (the tracker moved).
/// Returns the samples, and when registered apart that registration and the
/// identification, which the caller may reuse ([`Registered::refined_by`]). `apart` without
/// a registration is read as it is; the callers refuse it first.
///
/// # Errors
///
/// As [`Registered::samples_registered_apart`], or the identification's error.
pub fn read_validation(
    input: Input<'_>,
    columns: &ColumnMap,
    read: &ReadOptions,
    registered: Option<&Registered>,
    apart: Option<(&SampleSet, &CalibrateOptions)>,
) -> Result<(SampleSet, Option<(Registration, Calibration)>), MeasuredError> {
    match (registered, apart) {
        (Some(r), Some((samples, options))) => {
            let calibration = identify(&r.robot, samples, options)?;
            let (registration, validation) =
                r.samples_registered_apart(&calibration, input, columns, read)?;
            Ok((validation, Some((registration, calibration))))
        }
        (Some(r), None) => Ok((r.samples(input, columns, read)?, None)),
        (None, _) => Ok((input.samples(columns, read)?, None)),
    }
}

/// Tracker-frame measurements registered to a robot: what reads further series taken in
/// the same tracker frame, or after the tracker moved, into the same base frame.
#[derive(Debug, Clone)]
pub struct Registered {
    /// The registration.
    pub registration: Registration,
    /// The robot with the registered probe as its tool: the model every method starts
    /// from.
    pub robot: Robot,
    /// The robot as its file describes it: the registration's nominal flange poses.
    pub file_robot: Robot,
}

impl Registered {
    /// Reads tracker-frame measurements and registers them to `robot`: the registration
    /// and the registered base-frame samples.
    ///
    /// # Errors
    ///
    /// The file's reading error; [`MeasuredError::Register`] when the measurements do not
    /// fit the robot or cannot fix the registration.
    pub fn read(
        input: Input<'_>,
        columns: &ColumnMap,
        read: &ReadOptions,
        robot: Robot,
    ) -> Result<(Registered, SampleSet), MeasuredError> {
        let measurements = input.measurements(columns, read)?;
        Registered::from_measurements(input.name(), &measurements, robot)
    }

    /// Registers tracker-frame measurements read already (`name` names them in messages)
    /// to `robot`, as [`Registered::read`] does.
    ///
    /// # Errors
    ///
    /// As [`Registered::read`].
    pub fn from_measurements(
        name: &Path,
        measurements: &Measurements,
        robot: Robot,
    ) -> Result<(Registered, SampleSet), MeasuredError> {
        let failed = |source| MeasuredError::Register {
            path: name.to_path_buf(),
            source,
        };
        let registration =
            register(&robot, measurements, &RegisterOptions::default()).map_err(failed)?;
        let registered = Registered {
            robot: registration.robot(&robot)?,
            registration,
            file_robot: robot,
        };
        let samples = registered
            .registration
            .to_samples(&registered.file_robot, measurements)
            .map_err(failed)?;
        Ok((registered, samples))
    }

    /// Reads more tracker-frame measurements (same tracker frame, same probe) as samples
    /// through this registration.
    ///
    /// # Errors
    ///
    /// As [`Registered::read`].
    pub fn samples(
        &self,
        input: Input<'_>,
        columns: &ColumnMap,
        read: &ReadOptions,
    ) -> Result<SampleSet, MeasuredError> {
        let measurements = input.measurements(columns, read)?;
        self.to_samples(&input, &measurements)
    }

    /// Reads tracker-frame measurements taken after the tracker moved (another series) as
    /// samples: the robot's frame in the new tracker frame fitted to the TCP positions
    /// `calibration` (made from this registration's samples) predicts, the probe kept
    /// ([`register_moved`]). Returns that registration with the samples.
    ///
    /// # Errors
    ///
    /// As [`Registered::read`].
    pub fn samples_registered_apart(
        &self,
        calibration: &Calibration,
        input: Input<'_>,
        columns: &ColumnMap,
        read: &ReadOptions,
    ) -> Result<(Registration, SampleSet), MeasuredError> {
        let measurements = input.measurements(columns, read)?;
        // Fitted to the TCP the whole identified model predicts: its joint-space terms
        // move the joints the calibrated robot is evaluated at.
        let mut moved = measurements.clone();
        if !calibration.joint_terms().is_none() {
            let n = moved.joints.count();
            let mut joints = adwi_samples::Joints::new(n);
            for q in measurements.joints.rows() {
                match calibration.joint_terms().joints(q) {
                    Some(m) => joints.push(&m[..n]),
                    None => joints.push(q),
                }
            }
            moved.joints = joints;
        }
        let registration =
            register_moved(&self.registration, calibration.calibrated_robot(), &moved)
                .map_err(MeasuredError::register(&input))?;
        let samples = registration
            .to_samples(&self.file_robot, &measurements)
            .map_err(MeasuredError::register(&input))?;
        Ok((registration, samples))
    }

    /// Both transforms as the identification of all the registered `samples` refines them:
    /// `identified` when the caller has made it ([`read_validation`]), otherwise made here
    /// with `options`.
    ///
    /// # Errors
    ///
    /// The identification's error.
    pub fn refined_by(
        &self,
        samples: &SampleSet,
        options: &CalibrateOptions,
        identified: Option<&Calibration>,
    ) -> Result<Refined, MeasuredError> {
        let made;
        let calibration = match identified {
            Some(c) => c,
            None => {
                made = identify(&self.robot, samples, options)?;
                &made
            }
        };
        Ok(self.registration.refined(calibration, samples))
    }

    fn to_samples(
        &self,
        input: &Input<'_>,
        measurements: &Measurements,
    ) -> Result<SampleSet, MeasuredError> {
        self.registration
            .to_samples(&self.file_robot, measurements)
            .map_err(MeasuredError::register(input))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The UR10's robot file and the first rows of its series C, as the README maps them.
    fn ur10() -> (Robot, Vec<u8>, ColumnMap) {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables/ur10");
        let robot = Robot::load(root.join("robot.toml")).unwrap();
        let text = std::fs::read_to_string(
            root.join("measurements/Series_C/measurements_random_poses.csv"),
        )
        .unwrap();
        let head: String = text.lines().take(61).map(|l| format!("{l}\n")).collect();
        let columns = ColumnMap::parse(
            "j1=shoulder_pan_joint:rad,j2=shoulder_lift_joint:rad,j3=elbow_joint:rad,\
             j4=wrist_1_joint:rad,j5=wrist_2_joint:rad,j6=wrist_3_joint:rad,\
             mx=measurement_x,my=measurement_y,mz=measurement_z,\
             mex=measurement_rx:deg,mey=measurement_ry:deg,mez=measurement_rz:deg",
        )
        .unwrap();
        (robot, head.into_bytes(), columns)
    }

    #[test]
    fn tracker_measurements_in_memory_read_as_registered_samples() {
        let (robot, bytes, columns) = ur10();
        let input = Input::Memory {
            name: Path::new("<c>"),
            bytes: &bytes,
        };
        let read = ReadOptions::default();
        let (registered, samples) = read_samples(input, &columns, &read, Some(robot)).unwrap();
        let registered = registered.unwrap();
        assert_eq!(samples.len(), 60);
        assert_eq!(registered.registration.rows, 60);
        assert!(registered.registration.orientation);
        // The T-Mac probe sits about 93 mm along the flange axis (docs/tracker.md).
        let probe = registered.robot.tool().translation_mm;
        assert!((probe[2] - 93.0).abs() < 2.0, "{probe:?}");
        // The same rows read again through the registration give the same samples.
        let again = registered.samples(input, &columns, &read).unwrap();
        assert_eq!(again.error_mm, samples.error_mm);
        // Rigid registration leaves the UR10's own errors, a few mm at most.
        assert!(samples
            .error_mm
            .iter()
            .all(|e| e.iter().all(|v| v.abs() < 5.0)));
    }

    #[test]
    fn too_few_rows_are_refused_naming_the_input() {
        let (robot, bytes, columns) = ur10();
        let text = String::from_utf8(bytes).unwrap();
        let head: String = text.lines().take(4).map(|l| format!("{l}\n")).collect();
        let input = Input::Memory {
            name: Path::new("<few>"),
            bytes: head.as_bytes(),
        };
        let e = read_samples(input, &columns, &ReadOptions::default(), Some(robot)).unwrap_err();
        assert_eq!(e.to_string(), "cannot register <few>");
        assert!(matches!(
            e,
            MeasuredError::Register {
                source: RegisterError::Degenerate { rows: 3 },
                ..
            }
        ));
    }

    #[test]
    fn without_a_robot_the_file_is_read_as_base_frame_samples() {
        let input = Input::Memory {
            name: Path::new("<base>"),
            bytes: b"x,y,z,dx,dy,dz\n0,0,0,0.1,0.2,0.3\n",
        };
        let (registered, samples) =
            read_samples(input, &ColumnMap::default(), &ReadOptions::default(), None).unwrap();
        assert!(registered.is_none());
        assert_eq!(samples.error_mm, vec![[0.1, 0.2, 0.3]]);
    }
}
