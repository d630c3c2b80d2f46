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

use adwi_robot::calibrate::{identify, CalibrateOptions};
use adwi_robot::measured::{MeasuredError, Registered};
use adwi_robot::register::{register_moved, Registration};
use adwi_robot::Robot;
use adwi_samples::{ColumnMap, Measurements, ReadOptions, SampleSet};

use crate::inputs::Source;
use crate::JobError;

/// How many times the later series are registered again to the robot identified from all
/// series, after their registration to the first series' calibration.
pub const REFINEMENTS: usize = 1;

/// The series read as one sample set in the robot's base frame.
pub(crate) struct Series {
    /// Every sample, series after series.
    pub samples: SampleSet,
    /// Tracker-frame series: the first one's registration, with the robot every method
    /// starts from (the registered probe as its tool).
    pub registered: Option<Registered>,
    /// Tracker-frame series: the registrations of the second series on.
    pub others: Vec<Registration>,
    /// What registers the later series again once the robot is identified.
    later: Option<Later>,
}

/// Tracker-frame series after the first, kept to be registered again.
struct Later {
    names: Vec<std::path::PathBuf>,
    measurements: Vec<Measurements>,
    first_samples: SampleSet,
}

/// Reads `sources` as one sample set: registered to `tracker_robot` when given (their
/// poses are in a tracker's frames), otherwise as they are. Series after the first are
/// registered to the nominal robot here; [`Series::refine`] registers them again to the
/// robot identified from all of them (work a job does in its `run`, after every check).
///
/// # Errors
///
/// A file's reading error, a registration failing, series with different columns.
pub(crate) fn read(
    sources: &[Source],
    columns: &ColumnMap,
    read: &ReadOptions,
    tracker_robot: Option<Robot>,
) -> Result<Series, JobError> {
    let Some(robot) = tracker_robot else {
        let sets = sources
            .iter()
            .map(|s| s.input().samples(columns, read))
            .collect::<Result<Vec<_>, _>>()?;
        return Ok(Series {
            samples: concat(sets)?,
            registered: None,
            others: Vec::new(),
            later: None,
        });
    };
    let (first, rest) = sources
        .split_first()
        .ok_or_else(|| JobError::Options("give the samples file".into()))?;
    let (registered, first_samples) = Registered::read(first.input(), columns, read, robot)?;
    if rest.is_empty() {
        return Ok(Series {
            samples: first_samples,
            registered: Some(registered),
            others: Vec::new(),
            later: None,
        });
    }
    let later = Later {
        names: rest.iter().map(|s| s.name().to_path_buf()).collect(),
        measurements: rest
            .iter()
            .map(|s| s.input().measurements(columns, read))
            .collect::<Result<_, _>>()?,
        first_samples,
    };
    let (others, samples) = later.register(&registered, &registered.robot)?;
    Ok(Series {
        samples,
        registered: Some(registered),
        others,
        later: Some(later),
    })
}

impl Series {
    /// What the samples and their registrations warn about: samples that look like
    /// another unit, registrations no robot's error explains.
    pub(crate) fn warnings(&self) -> Vec<crate::Warning> {
        let mut out: Vec<crate::Warning> = self
            .samples
            .plausibility_warnings()
            .into_iter()
            .map(crate::Warning::Samples)
            .collect();
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
        let (Some(later), Some(registered)) = (&self.later, &self.registered) else {
            return Ok(());
        };
        // The first series' own calibration: what the others are registered to first, so
        // that no series' misregistration has yet leaked into the model.
        let first = identify(&registered.robot, &later.first_samples, calibrate)?;
        (self.others, self.samples) = later.register(registered, first.calibrated_robot())?;
        for _ in 0..REFINEMENTS {
            let calibration = identify(&registered.robot, &self.samples, calibrate)?;
            (self.others, self.samples) =
                later.register(registered, calibration.calibrated_robot())?;
        }
        Ok(())
    }
}

impl Later {
    /// The later series registered to `model` (the probe the first series'): their
    /// transforms, and every series' samples together.
    fn register(
        &self,
        first: &Registered,
        model: &Robot,
    ) -> Result<(Vec<Registration>, SampleSet), JobError> {
        let mut sets = vec![self.first_samples.clone()];
        let mut registrations = Vec::new();
        for (name, m) in self.names.iter().zip(&self.measurements) {
            let failed = |source| MeasuredError::Register {
                path: name.clone(),
                source,
            };
            let r = register_moved(&first.registration, model, m).map_err(failed)?;
            sets.push(r.to_samples(&first.file_robot, m).map_err(failed)?);
            registrations.push(r);
        }
        Ok((registrations, concat(sets)?))
    }
}

fn concat(sets: Vec<SampleSet>) -> Result<SampleSet, JobError> {
    if sets.len() == 1 {
        return Ok(sets.into_iter().next().expect("one"));
    }
    SampleSet::concat(&sets).map_err(|e| JobError::Options(e.to_string()))
}
