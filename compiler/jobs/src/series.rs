//! Several measurement series trained together: one sample set in the robot's base frame.
//!
//! In the base frame the series are simply one after the other
//! ([`SampleSet::concat`]). In a laser tracker's frame each series has a tracker-to-base
//! transform of its own (the tracker was moved between series) and they share the robot:
//! its kinematic parameters and the probe on its flange. The first series is registered
//! as a single one is ([`Registered::read`]: a rigid fit of the nominal robot, probe
//! included); every other one is registered to it with the probe kept
//! ([`register_moved`]): to the TCP positions of the nominal robot when the files are
//! read (enough to size the work), then to those of the robot identified from the first
//! series alone — no other series' misregistration has leaked into that model, and
//! measurements a model fits exactly are then registered exactly — and then
//! [`REFINEMENTS`] times to the robot identified from every series together, so that each
//! series' transform is fitted to the model the others are expressed in (one step of block
//! coordinate descent, the transforms given the model and the model given the
//! transforms, towards their joint least-squares fit).

use adwi_identify::agreement;
use adwi_identify::calibrate::{identify, CalibrateOptions, Calibration};
use adwi_identify::measured::{MeasuredError, Registered};
use adwi_identify::register::{register_moved, Registration};
use adwi_robot::Robot;
use adwi_runtime::joint_terms::JointTerms;
use adwi_samples::{check_series, ColumnMap, Measurements, ReadOptions, SampleSet, SeriesRows};

use crate::inputs::Source;
use crate::JobError;

/// How many times the later series are registered again to the robot identified from all
/// series, after their registration to the first series' calibration.
pub const REFINEMENTS: usize = 1;

/// The series read as one sample set in the robot's base frame.
pub(crate) struct Series {
    /// Every sample, series after series.
    pub samples: SampleSet,
    /// The series of each sample (its file's index), when several were read: a pose two
    /// series command alike is one sample, the first series'.
    pub labels: Option<Vec<usize>>,
    /// Tracker-frame series: the first one's registration, with the robot every method
    /// starts from (the registered probe as its tool).
    pub registered: Option<Registered>,
    /// Tracker-frame series: the registrations of the second series on.
    pub others: Vec<Registration>,
    /// What registers the later series again once the robot is identified.
    later_series: Option<LaterSeries>,
    /// Series the robot file fits only with another tool or base frame.
    agreement: Vec<crate::Warning>,
}

/// Tracker-frame series after the first, kept to be registered again.
struct LaterSeries {
    names: Vec<std::path::PathBuf>,
    measurements: Vec<Measurements>,
    first_samples: SampleSet,
}

/// Reads `sources` as one sample set: registered to `robot` when `tracker` (their poses
/// are in a tracker's frames), otherwise as they are. Series after the first are
/// registered to the nominal robot here; [`Series::refine`] registers them again to the
/// robot identified from all of them (work a job does in its `run`, after every check).
///
/// Samples that cannot be right are refused here, before any work: a series given twice or
/// in another length unit than the others ([`check_series`]), and with a robot, samples
/// its nominal forward kinematics does not put near their positions
/// ([`adwi_identify::agreement`]: base-frame samples as read, tracker-frame ones as
/// registered).
///
/// # Errors
///
/// A file's reading error, a registration failing, series with different columns, series
/// that conflict, samples that disagree with the robot.
pub(crate) fn read(
    sources: &[Source],
    columns: &ColumnMap,
    read: &ReadOptions,
    robot: Option<&Robot>,
    tracker: bool,
) -> Result<Series, JobError> {
    let robot = match robot {
        Some(robot) if tracker => robot.clone(),
        _ => {
            let sets = sources
                .iter()
                .map(|s| s.input().samples(columns, read))
                .collect::<Result<Vec<_>, _>>()?;
            check_series(&rows(sources, &sets, |s| &s.nominal_mm))?;
            let mut warnings = Vec::new();
            if let Some(robot) = robot {
                for (source, set) in sources.iter().zip(&sets) {
                    let agreed = agreement::check_base_frame(robot, set, source.name())?;
                    if let Some(fitting) = agreed.reading {
                        warnings.push(crate::Warning::Agreement {
                            path: source.name().to_path_buf(),
                            fitting,
                        });
                    }
                }
            }
            let (samples, labels) = concat(sets)?;
            return Ok(Series {
                samples,
                labels,
                registered: None,
                others: Vec::new(),
                later_series: None,
                agreement: warnings,
            });
        }
    };
    let mut measurements = sources
        .iter()
        .map(|s| s.input().measurements(columns, read))
        .collect::<Result<Vec<_>, _>>()?;
    check_series(&rows(sources, &measurements, |m| &m.measured_mm))?;
    let (first, rest) = sources
        .split_first()
        .ok_or_else(|| JobError::Options("give the samples file".into()))?;
    let first_measurements = measurements.remove(0);
    let (registered, first_samples) =
        Registered::from_measurements(first.name(), &first_measurements, robot)?;
    agreement::check_registered(
        &registered.file_robot,
        &first_measurements,
        &first_samples,
        first.name(),
    )?;
    if rest.is_empty() {
        return Ok(Series {
            samples: first_samples,
            labels: None,
            registered: Some(registered),
            others: Vec::new(),
            later_series: None,
            agreement: Vec::new(),
        });
    }
    let later = LaterSeries {
        names: rest.iter().map(|s| s.name().to_path_buf()).collect(),
        measurements,
        first_samples,
    };
    let (others, sets) = later.register_each(&registered, &registered.robot, &JointTerms::NONE)?;
    for ((name, m), set) in later.names.iter().zip(&later.measurements).zip(&sets[1..]) {
        agreement::check_registered(&registered.file_robot, m, set, name)?;
    }
    let (samples, labels) = concat(sets)?;
    Ok(Series {
        samples,
        labels,
        registered: Some(registered),
        others,
        later_series: Some(later),
        agreement: Vec::new(),
    })
}

/// The series as [`check_series`] sees them, with `positions` of each one's contents.
fn rows<'a, T>(
    sources: &'a [Source],
    contents: &'a [T],
    positions: fn(&T) -> &Vec<[f64; 3]>,
) -> Vec<SeriesRows<'a, T>> {
    sources
        .iter()
        .zip(contents)
        .map(|(source, content)| SeriesRows {
            name: source.name(),
            file: source.path(),
            content,
            positions_mm: positions(content),
        })
        .collect()
}

impl Series {
    /// What the samples and their registrations warn about: samples that look like
    /// another unit, registrations no robot's error explains.
    pub(crate) fn warnings(&self) -> Vec<crate::Warning> {
        let mut out: Vec<crate::Warning> = self.agreement.clone();
        out.extend(
            self.samples
                .plausibility_warnings()
                .into_iter()
                .map(crate::Warning::Samples),
        );
        let registrations = self
            .registered
            .iter()
            .map(|r| &r.registration)
            .chain(&self.others);
        for r in registrations {
            out.extend(r.warnings.iter().cloned().map(crate::Warning::Registration));
        }
        out
    }

    /// Registers the series after the first again: to the robot identified from the
    /// first series, then [`REFINEMENTS`] times to the robot identified from all of them
    /// (module docs); nothing for a single series.
    ///
    /// # Errors
    ///
    /// The identification or a registration failing.
    pub(crate) fn refine(&mut self, calibrate: &CalibrateOptions) -> Result<(), JobError> {
        let (Some(later), Some(registered)) = (&self.later_series, &self.registered) else {
            return Ok(());
        };
        // The first series' own calibration: what the others are registered to first, so
        // that no series' misregistration has yet leaked into the model.
        let first = identify(&registered.robot, &later.first_samples, calibrate)?;
        (self.others, (self.samples, self.labels)) = later.register(registered, &first)?;
        for _ in 0..REFINEMENTS {
            let calibration = identify(&registered.robot, &self.samples, calibrate)?;
            (self.others, (self.samples, self.labels)) =
                later.register(registered, &calibration)?;
        }
        Ok(())
    }
}

impl LaterSeries {
    /// The later series registered to the model `calibration` identified (the probe the
    /// first series'; the TCP its joint-space terms move too): their transforms, and
    /// every series' samples together.
    fn register(
        &self,
        first: &Registered,
        model: &Calibration,
    ) -> Result<(Vec<Registration>, Labelled), JobError> {
        let (registrations, sets) =
            self.register_each(first, model.calibrated_robot(), model.joint_terms())?;
        Ok((registrations, concat(sets)?))
    }

    /// As [`LaterSeries::register`], every series' samples apart, the first series' first.
    fn register_each(
        &self,
        first: &Registered,
        model: &Robot,
        terms: &JointTerms,
    ) -> Result<(Vec<Registration>, Vec<SampleSet>), JobError> {
        let mut sets = vec![self.first_samples.clone()];
        let mut registrations = Vec::new();
        for (name, m) in self.names.iter().zip(&self.measurements) {
            let failed = |source| MeasuredError::Register {
                path: name.clone(),
                source,
            };
            let r = register_moved(&first.registration, model, &moved_by_terms(m, terms))
                .map_err(failed)?;
            sets.push(r.to_samples(&first.file_robot, m).map_err(failed)?);
            registrations.push(r);
        }
        Ok((registrations, sets))
    }
}

/// `m` with its joints where the joint-space terms `terms` move them: what a model with
/// terms stands at (the measurements themselves when it has none).
fn moved_by_terms<'a>(
    m: &'a Measurements,
    terms: &JointTerms,
) -> std::borrow::Cow<'a, Measurements> {
    if terms.is_none() {
        return std::borrow::Cow::Borrowed(m);
    }
    let n = m.joints.count();
    let mut joints = adwi_samples::Joints::new(n);
    for q in m.joints.rows() {
        match terms.joints(q) {
            Some(moved) => joints.push(&moved[..n]),
            None => joints.push(q),
        }
    }
    let mut moved = m.clone();
    moved.joints = joints;
    std::borrow::Cow::Owned(moved)
}

/// Samples, and the series of each when several were read.
type Labelled = (SampleSet, Option<Vec<usize>>);

/// The series as one sample set, and the series of each sample when several.
fn concat(sets: Vec<SampleSet>) -> Result<Labelled, JobError> {
    if sets.len() == 1 {
        return Ok((sets.into_iter().next().expect("one"), None));
    }
    let samples = SampleSet::concat(&sets).map_err(|e| JobError::Options(e.to_string()))?;
    let labels = labels(&sets, &samples);
    Ok((samples, Some(labels)))
}

/// The series of each of `merged`'s samples: the first of `sets` that commands its pose
/// (nominal position to the nanometre and joint values to the nanoradian), else the first.
fn labels(sets: &[SampleSet], merged: &SampleSet) -> Vec<usize> {
    let key = |set: &SampleSet, i: usize| {
        let mut key: Vec<i64> = set.nominal_mm[i]
            .iter()
            .map(|v| (v * 1e6).round() as i64)
            .collect();
        if let Some(q) = set.joints_rad(i) {
            key.extend(q.iter().map(|v| (v * 1e9).round() as i64));
        }
        key
    };
    let mut first = std::collections::HashMap::new();
    for (series, set) in sets.iter().enumerate() {
        for i in 0..set.len() {
            first.entry(key(set, i)).or_insert(series);
        }
    }
    (0..merged.len())
        .map(|i| first.get(&key(merged, i)).copied().unwrap_or(0))
        .collect()
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use adwi_identify::agreement::{Disagreement, Reading as Fit, UnitMistake};
    use adwi_samples::SeriesConflict;

    use crate::args::{Reading, RobotArgs};
    use crate::{BuildArgs, BuildJob, CalibrateArgs, CalibrateJob, JobError, Source};

    fn shipped(path: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tables")
            .join(path)
    }

    /// The README's column map of the UR5 measurements.
    const UR5_MAP: &str = "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,j1=joint_1,j2=joint_2,\
                           j3=joint_3,j4=joint_4,j5=joint_5,j6=joint_6";

    /// The UR5 grid with its joint columns (7..12) or its position columns (1..6) turned
    /// into another unit by `convert`, in memory.
    fn ur5_grid(columns: std::ops::Range<usize>, convert: impl Fn(f64) -> f64) -> Source {
        ur5_grid_edited(|_, column, v| {
            if columns.contains(&column) {
                convert(v)
            } else {
                v
            }
        })
    }

    /// The UR5 grid with every value `edit(row, column, value)` (rows from 0 after the
    /// header), in memory.
    fn ur5_grid_edited(edit: impl Fn(usize, usize, f64) -> f64) -> Source {
        let text = std::fs::read_to_string(shipped(
            "ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv",
        ))
        .unwrap();
        let mut lines = text.lines();
        let mut out = format!("{}\n", lines.next().unwrap());
        for (row, line) in lines.enumerate() {
            let fields: Vec<String> = line
                .split(',')
                .enumerate()
                .map(|(i, f)| format!("{}", edit(row, i, f.parse::<f64>().unwrap())))
                .collect();
            out.push_str(&fields.join(","));
            out.push('\n');
        }
        Source::Memory {
            name: "ur5-converted.csv".into(),
            bytes: out.into_bytes(),
        }
    }

    fn build(samples: Vec<Source>, robot: Option<&str>, map: &str) -> Result<BuildJob, JobError> {
        BuildJob::new(BuildArgs {
            samples,
            output: std::env::temp_dir().join("never-written.tbl"),
            reading: Reading {
                columns: Some(map.into()),
                ..Reading::default()
            },
            robot: RobotArgs {
                robot: robot.map(shipped),
                ..RobotArgs::default()
            },
            ..BuildArgs::default()
        })
    }

    #[test]
    fn ur5_joints_in_radians_read_as_degrees_are_refused_with_the_unit() {
        let e = build(
            vec![ur5_grid(7..13, f64::to_radians)],
            Some("ur5/robot.toml"),
            UR5_MAP,
        )
        .err()
        .expect("refused");
        let JobError::Disagreement(d) = &e else {
            panic!("{e}")
        };
        let Disagreement::Systematic {
            missed,
            samples,
            fitting: Some(fitting),
            ..
        } = d.as_ref()
        else {
            panic!("{e}")
        };
        assert_eq!((*missed, *samples), (1000, 1000), "{e}");
        assert_eq!(
            fitting.reading,
            Fit::Units(vec![UnitMistake::JointsInRadians])
        );
        assert!(fitting.worst_mm < 1.0, "{e}");
        assert!(
            e.to_string()
                .contains("they fit with the joint values in radians"),
            "{e}"
        );
        println!("{e}");
    }

    #[test]
    fn ur5_positions_in_metres_are_refused_with_the_unit() {
        let e = build(
            vec![ur5_grid(1..7, |v| v / 1000.0)],
            Some("ur5/robot.toml"),
            UR5_MAP,
        )
        .err()
        .expect("refused");
        let JobError::Disagreement(d) = &e else {
            panic!("{e}")
        };
        let Disagreement::Systematic {
            fitting: Some(fitting),
            ..
        } = d.as_ref()
        else {
            panic!("{e}")
        };
        assert_eq!(
            fitting.reading,
            Fit::Units(vec![UnitMistake::PositionsInMetres]),
            "{e}"
        );
        assert!(
            e.to_string()
                .contains("give the position columns the unit m"),
            "{e}"
        );
    }

    /// The KR150-2's samples identified with the UR5's robot file: no reading fits, and
    /// the message asks whether the robot file is this robot's.
    #[test]
    fn kr150_samples_with_the_ur5_robot_file_are_refused() {
        let e = CalibrateJob::new(CalibrateArgs {
            samples: vec![Source::File(shipped("kr150-2/samples.csv"))],
            robot: RobotArgs {
                robot: Some(shipped("ur5/robot.toml")),
                ..RobotArgs::default()
            },
            ..CalibrateArgs::default()
        })
        .err()
        .expect("refused");
        let JobError::Disagreement(d) = &e else {
            panic!("{e}")
        };
        let Disagreement::Systematic {
            missed,
            samples,
            median_mm,
            fitting: None,
            ..
        } = d.as_ref()
        else {
            panic!("{e}")
        };
        assert_eq!((*missed, *samples), (729, 729), "{e}");
        assert!(*median_mm > 500.0, "{e}");
        assert!(
            e.to_string().contains("is the robot file this robot's"),
            "{e}"
        );
        // With its own robot file the same samples are accepted.
        CalibrateJob::new(CalibrateArgs {
            samples: vec![Source::File(shipped("kr150-2/samples.csv"))],
            robot: RobotArgs {
                robot: Some(shipped("kr150-2/robot.toml")),
                ..RobotArgs::default()
            },
            ..CalibrateArgs::default()
        })
        .unwrap();
    }

    /// Three damaged rows among a thousand good ones (a joint off by 20°) are named by
    /// line, not dropped.
    #[test]
    fn a_few_rows_the_robot_does_not_fit_are_named_by_line() {
        let damaged = [10, 400, 998];
        let samples = ur5_grid_edited(|row, column, v| {
            if column == 8 && damaged.contains(&row) {
                v + 20.0
            } else {
                v
            }
        });
        let e = build(vec![samples], Some("ur5/robot.toml"), UR5_MAP)
            .err()
            .expect("refused");
        let JobError::Disagreement(d) = &e else {
            panic!("{e}")
        };
        let Disagreement::Outliers { outliers, .. } = d.as_ref() else {
            panic!("{e}")
        };
        let lines: Vec<u64> = outliers.iter().map(|m| m.line).collect();
        // Row r is on line r + 2, after the header.
        assert_eq!(lines, [12, 402, 1000], "{e}");
        assert!(
            e.to_string().contains("correct or remove these rows"),
            "{e}"
        );
    }

    #[test]
    fn the_same_series_twice_is_refused() {
        let grid = shipped("ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv");
        let e = build(
            vec![Source::File(grid.clone()), Source::File(grid.clone())],
            None,
            UR5_MAP,
        )
        .err()
        .expect("refused");
        assert!(
            matches!(&e, JobError::Series(c) if matches!(c.as_ref(), SeriesConflict::SameFile { first: 1, again: 2, .. })),
            "{e}"
        );
        // A copy of it (here in memory): the same rows.
        let e = build(
            vec![Source::File(grid), ur5_grid(0..0, |v| v)],
            None,
            UR5_MAP,
        )
        .err()
        .expect("refused");
        assert!(
            matches!(&e, JobError::Series(c) if matches!(c.as_ref(), SeriesConflict::SameRows { again: 2, .. })),
            "{e}"
        );
    }

    #[test]
    fn a_series_in_metres_among_series_in_millimetres_is_refused_by_name() {
        let measurements = shipped("ur5/measurements");
        let e = build(
            vec![
                Source::File(measurements.join("3D_UR5_uncalibrated_grid_cleaned.csv")),
                Source::File(measurements.join("3D_UR5_uncalibrated_random_cleaned.csv")),
                ur5_grid(1..7, |v| v / 1000.0),
            ],
            None,
            UR5_MAP,
        )
        .err()
        .expect("refused");
        assert!(
            matches!(&e, JobError::Series(c) if matches!(c.as_ref(), SeriesConflict::Scale { series: 3, .. })),
            "{e}"
        );
        assert!(
            e.to_string().contains("series 3 (ur5-converted.csv)"),
            "{e}"
        );
        assert!(e.to_string().contains("metres read as millimetres"), "{e}");
    }

    /// The UR10's tracker-frame series C with its joints (radians) read as degrees: the
    /// registration cannot fit them, and registered again with the joints in radians they
    /// fit.
    #[test]
    fn tracker_measurements_with_joints_in_the_wrong_unit_are_refused_after_registration() {
        let text = std::fs::read_to_string(shipped(
            "ur10/measurements/Series_C/measurements_random_poses.csv",
        ))
        .unwrap();
        let head: String = text.lines().take(301).map(|l| format!("{l}\n")).collect();
        let map = |unit: &str| {
            format!(
                "j1=shoulder_pan_joint{unit},j2=shoulder_lift_joint{unit},j3=elbow_joint{unit},\
                 j4=wrist_1_joint{unit},j5=wrist_2_joint{unit},j6=wrist_3_joint{unit},\
                 mx=measurement_x,my=measurement_y,mz=measurement_z"
            )
        };
        let job = |unit: &str| {
            BuildJob::new(BuildArgs {
                samples: vec![Source::Memory {
                    name: "series-c.csv".into(),
                    bytes: head.clone().into_bytes(),
                }],
                output: std::env::temp_dir().join("never-written.tbl"),
                reading: Reading {
                    columns: Some(map(unit)),
                    ..Reading::default()
                },
                robot: RobotArgs {
                    robot: Some(shipped("ur10/robot.toml")),
                    ..RobotArgs::default()
                },
                measured_in: crate::Frame::Tracker,
                ..BuildArgs::default()
            })
        };
        job(":rad").unwrap();
        let e = job("").err().expect("refused");
        let JobError::Disagreement(d) = &e else {
            panic!("{e}")
        };
        let Disagreement::Systematic {
            fitting: Some(fitting),
            ..
        } = d.as_ref()
        else {
            panic!("{e}")
        };
        assert_eq!(
            fitting.reading,
            Fit::Units(vec![UnitMistake::JointsInRadians]),
            "{e}"
        );
        assert!(
            e.to_string().contains("registered to the robot file"),
            "{e}"
        );
    }
}

#[cfg(test)]
mod label_tests {
    use adwi_samples::SampleSet;

    /// Samples at `x` (mm) along the base's x axis, errors zero.
    fn at(x: &[f64]) -> SampleSet {
        SampleSet {
            nominal_mm: x.iter().map(|&x| [x, 0.0, 0.0]).collect(),
            error_mm: vec![[0.0; 3]; x.len()],
            lines: (1..=x.len() as u64).collect(),
            ..SampleSet::default()
        }
    }

    #[test]
    fn each_sample_is_labelled_with_its_series_and_a_shared_pose_with_the_first() {
        let (samples, labels) =
            super::concat(vec![at(&[0.0, 10.0]), at(&[20.0, 10.0, 30.0])]).unwrap();
        let labels = labels.unwrap();
        assert_eq!(labels.len(), samples.len());
        for (i, p) in samples.nominal_mm.iter().enumerate() {
            let expected = if p[0] == 20.0 || p[0] == 30.0 { 1 } else { 0 };
            assert_eq!(labels[i], expected, "sample at {p:?}");
        }
        assert!(super::concat(vec![at(&[0.0])]).unwrap().1.is_none());
    }
}
