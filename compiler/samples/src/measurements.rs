//! Raw measurements: the poses a robot was commanded to and what an instrument measured,
//! in the instrument's frame.

use std::fmt;

use nalgebra::Rotation3;

use super::repeats::{self, Parts};
use super::{Joints, SampleSet};
use crate::pose;

/// Measurements as taken, before any registration: per row, the joint values the robot
/// was at, the nominal pose when the file gives it, and the measured pose **in the frame of
/// the measuring instrument** (a laser tracker's own frame, say), which is not the robot's
/// base frame until a registration has found the transform between them. No errors are
/// computed here: measured and nominal poses are in different frames.
///
/// A registration (identifying the instrument-to-base and the target-to-flange transforms
/// from the joints and the measured poses) consumes this and produces an ordinary
/// base-frame [`SampleSet`]: it expresses the measured poses in the base frame (and may set
/// the nominal poses from the joints by forward kinematics), then calls
/// [`Measurements::to_samples`]. For measurements already in the base frame,
/// [`Measurements::to_samples`] applies directly; the CSV reader computes the errors of
/// `mx,my,mz` and measured-orientation columns the same way.
///
/// Read by [`super::read_measurements`]: joints `j1..jn` and the measured position
/// `mx,my,mz` are required; nominal position `x,y,z`, a nominal orientation (`a,b,c` or
/// another convention) and a measured orientation (`ma,mb,mc`, ...) are optional. Every
/// vector has one entry per row, in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Measurements {
    /// Joint values the robot was at: rad, mm for prismatic joints; n per row.
    pub joints: Joints,
    /// Nominal (commanded) positions, mm, robot base frame, when given.
    pub nominal_mm: Option<Vec<[f64; 3]>>,
    /// Nominal orientations (the commanded frame in the base frame), when given.
    pub nominal_rotation: Option<Vec<Rotation3<f64>>>,
    /// Measured positions, mm, in the measuring instrument's frame.
    pub measured_mm: Vec<[f64; 3]>,
    /// Measured orientations (the measured target's frame in the instrument's frame), when
    /// given.
    pub measured_rotation: Option<Vec<Rotation3<f64>>>,
    /// Inverse-kinematics configurations, when given.
    pub config: Option<Vec<u8>>,
    /// The source line of each row (1-based), for messages.
    pub lines: Vec<u64>,
}

/// Why measurements do not make samples.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MeasurementsError {
    /// There are no nominal positions to take the errors from.
    NoNominalPositions,
    /// There are measured orientations but no nominal ones.
    NoNominalOrientations,
    /// A part does not have one entry per row.
    Length {
        /// The part.
        part: &'static str,
        /// Its entries.
        found: usize,
        /// The rows.
        rows: usize,
    },
}

impl fmt::Display for MeasurementsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MeasurementsError::NoNominalPositions => {
                write!(f, "no nominal positions: errors need them")
            }
            MeasurementsError::NoNominalOrientations => write!(
                f,
                "measured orientations without nominal ones: orientation errors need both"
            ),
            MeasurementsError::Length { part, found, rows } => {
                write!(f, "{found} {part} for {rows} rows")
            }
        }
    }
}

impl std::error::Error for MeasurementsError {}

impl Measurements {
    /// The number of rows.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// The joint count.
    pub fn joint_count(&self) -> usize {
        self.joints.count()
    }

    /// The samples of measurements taken in the robot's base frame: position errors
    /// `measured − nominal`, orientation errors `log(R_measured · R_nominalᵀ)` when both
    /// orientations are given; repeated poses folded as [`super::read_samples`] folds
    /// them.
    ///
    /// # Errors
    ///
    /// No nominal positions, measured orientations without nominal ones, or parts whose
    /// lengths differ from the row count.
    pub fn to_samples(&self) -> Result<SampleSet, MeasurementsError> {
        let rows = self.len();
        let check = |part: &'static str, found: usize| {
            if found == rows {
                Ok(())
            } else {
                Err(MeasurementsError::Length { part, found, rows })
            }
        };
        let nominal = self
            .nominal_mm
            .as_ref()
            .ok_or(MeasurementsError::NoNominalPositions)?;
        check("nominal positions", nominal.len())?;
        check("measured positions", self.measured_mm.len())?;
        check("joint rows", self.joints.len())?;
        if let Some(r) = &self.nominal_rotation {
            check("nominal orientations", r.len())?;
        }
        if let Some(r) = &self.measured_rotation {
            check("measured orientations", r.len())?;
        }
        if let Some(c) = &self.config {
            check("configurations", c.len())?;
        }
        let rotation_error_rad = match (&self.nominal_rotation, &self.measured_rotation) {
            (Some(n), Some(m)) => Some(orientation_errors(n, m)),
            (None, Some(_)) => return Err(MeasurementsError::NoNominalOrientations),
            _ => None,
        };
        Ok(repeats::fold(Parts {
            nominal_mm: nominal.clone(),
            error_mm: position_errors(nominal, self.measured_mm.clone()),
            nominal_rotation: self.nominal_rotation.clone(),
            rotation_error_rad,
            joints: Some(self.joints.clone()),
            config: self.config.clone(),
            lines: self.lines.clone(),
        }))
    }
}

/// The position errors `measured − nominal`, mm, computed in place of the measured
/// positions.
pub(crate) fn position_errors(nominal: &[[f64; 3]], mut measured: Vec<[f64; 3]>) -> Vec<[f64; 3]> {
    for (m, n) in measured.iter_mut().zip(nominal) {
        *m = [m[0] - n[0], m[1] - n[1], m[2] - n[2]];
    }
    measured
}

/// The base-frame orientation errors `log(R_measured · R_nominalᵀ)`, rad.
pub(crate) fn orientation_errors(
    nominal: &[Rotation3<f64>],
    measured: &[Rotation3<f64>],
) -> Vec<[f64; 3]> {
    nominal
        .iter()
        .zip(measured)
        .map(|(n, m)| pose::orientation_error(n, m))
        .collect()
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use approx::assert_abs_diff_eq;

    use super::super::{parse_measurements, parse_samples, ColumnMap, ReadOptions};
    use super::*;

    fn measurements(text: &str, map: &str) -> Result<Measurements, String> {
        parse_measurements(
            Path::new("m.csv"),
            text.as_bytes(),
            &ColumnMap::parse(map).unwrap(),
            &ReadOptions::default(),
        )
        .map_err(|e| e.to_string())
    }

    #[test]
    fn measurements_keep_the_instrument_frame() {
        let m = measurements(
            "t;j1;j2;mx;my;mz;mex;mey;mez;dx;dy;dz\n\
             1;90;0;2361,98;-1368,5;119,4;-90;0;0;x;x;x\n\
             2;0;45;1685,3;-1665,3;-415,8;0;0;90;x;x;x\n",
            "",
        )
        .unwrap();
        assert_eq!(m.len(), 2);
        assert_eq!(m.joint_count(), 2);
        assert_eq!(m.joints.row(0), [90f64.to_radians(), 0.0]);
        assert_eq!(m.measured_mm[0], [2361.98, -1368.5, 119.4]);
        assert!(m.nominal_mm.is_none() && m.nominal_rotation.is_none());
        let r = &m.measured_rotation.as_ref().unwrap()[1];
        assert_abs_diff_eq!(
            r.matrix(),
            pose::rotation_zyx_rad(90f64.to_radians(), 0.0, 0.0).matrix(),
            epsilon = 1e-15
        );
        assert_eq!(m.lines, vec![2, 3]);
        assert_eq!(m.to_samples(), Err(MeasurementsError::NoNominalPositions));
    }

    #[test]
    fn measurements_need_joints_and_measured_positions() {
        let err = measurements("x,y,z,mx,my,mz\n1,2,3,1,2,3\n", "").unwrap_err();
        assert!(
            err.contains("m.csv:1:") && err.contains("missing column j1..jn"),
            "{err}"
        );
        let err = measurements("x,y,z,dx,dy,dz,j1\n1,2,3,1,2,3,0\n", "").unwrap_err();
        assert!(err.contains("missing column mx,my,mz"), "{err}");
    }

    /// Measurements in the base frame make exactly the samples the sample reader makes of
    /// the same file: one path from measured poses to errors, repeats folded alike.
    #[test]
    fn base_frame_measurements_make_the_samples_the_reader_makes() {
        let text = "x,y,z,mx,my,mz,q1,q2,q3,q4,mroll,mpitch,myaw,j1,j2,config\n\
                    1000,0,500,1000.1,0.2,499.9,1,0,0,0,0.01,0,0,10,20,1\n\
                    1000,0,500,1000.3,0.2,499.9,1,0,0,0,0.02,0,0,10,20,1\n\
                    1000,0,500,1000.1,0.2,499.9,0,1,0,0,180,0.01,0,10,20,1\n\
                    1100,0,500,1100.1,0.2,499.9,1,0,0,0,0,0,0.03,11,21,1\n";
        let from_reader =
            parse_samples(Path::new("m.csv"), text.as_bytes(), &ColumnMap::default()).unwrap();
        let from_measurements = measurements(text, "").unwrap().to_samples().unwrap();
        assert_eq!(from_measurements, from_reader);
        assert_eq!(from_reader.len(), 3);
        assert_eq!(from_reader.repeats.as_ref().unwrap().rows, 2);
        assert_abs_diff_eq!(from_reader.error_mm[0][0], 0.2, epsilon = 1e-9);
        let r = from_reader.rotation_error_rad.as_ref().unwrap();
        assert_abs_diff_eq!(r[0][0], 0.015f64.to_radians(), epsilon = 1e-12);
        assert_abs_diff_eq!(r[1][1], 0.01f64.to_radians(), epsilon = 1e-12);
        assert_abs_diff_eq!(r[2][2], 0.03f64.to_radians(), epsilon = 1e-12);
    }

    #[test]
    fn inconsistent_measurements_make_no_samples() {
        let mut m = measurements("x,y,z,mx,my,mz,ma,mb,mc,j1\n1,2,3,1,2,3,0,0,0,0\n", "").unwrap();
        assert_eq!(
            m.to_samples(),
            Err(MeasurementsError::NoNominalOrientations)
        );
        m.measured_rotation = None;
        assert!(m.to_samples().is_ok());
        m.measured_mm.push([0.0; 3]);
        assert_eq!(
            m.to_samples(),
            Err(MeasurementsError::Length {
                part: "measured positions",
                found: 2,
                rows: 1
            })
        );
    }
}
