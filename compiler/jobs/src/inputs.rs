//! What a job reads: sample files (on disk or in memory), robot files, and the list of
//! every file read, against which every output is checked.

use std::path::{Path, PathBuf};

use adwi_identify::measured::Input;
use adwi_robot::Robot;

use crate::args::RobotArgs;
use crate::JobError;

/// A samples (or validation, or targets) file: a path, or CSV text in memory (a Python
/// DataFrame's, say) with the name messages give it.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A file.
    File(PathBuf),
    /// CSV text.
    Memory {
        /// What messages call it.
        name: PathBuf,
        /// The text.
        bytes: Vec<u8>,
    },
}

impl Source {
    /// The one reader's view of it.
    pub fn input(&self) -> Input<'_> {
        match self {
            Source::File(path) => Input::File(path),
            Source::Memory { name, bytes } => Input::Memory { name, bytes },
        }
    }

    /// Its path, when it is a file.
    pub fn path(&self) -> Option<&Path> {
        match self {
            Source::File(path) => Some(path),
            Source::Memory { .. } => None,
        }
    }

    /// What messages call it.
    pub fn name(&self) -> &Path {
        match self {
            Source::File(path) => path,
            Source::Memory { name, .. } => name,
        }
    }
}

impl From<PathBuf> for Source {
    fn from(path: PathBuf) -> Source {
        Source::File(path)
    }
}

impl std::str::FromStr for Source {
    type Err = std::convert::Infallible;

    fn from_str(text: &str) -> Result<Source, Self::Err> {
        Ok(Source::File(PathBuf::from(text)))
    }
}

/// Every file a job reads, however it was reached (a robot file's URDF included): no
/// output may be one of them.
#[derive(Debug, Clone, Default)]
pub(crate) struct Inputs {
    paths: Vec<PathBuf>,
}

impl Inputs {
    pub(crate) fn add(&mut self, path: &Path) {
        self.paths.push(path.to_path_buf());
    }

    pub(crate) fn add_sources<'a>(&mut self, sources: impl IntoIterator<Item = &'a Source>) {
        for s in sources {
            if let Some(p) = s.path() {
                self.add(p);
            }
        }
    }

    pub(crate) fn paths(&self) -> Vec<&Path> {
        self.paths.iter().map(PathBuf::as_path).collect()
    }
}

/// Loads the robot `args` names, if any, recording every file read as an input (the
/// robot file, and a URDF it names).
///
/// # Errors
///
/// [`JobError::Robot`] naming the file.
pub(crate) fn load_robot(args: &RobotArgs, inputs: &mut Inputs) -> Result<Option<Robot>, JobError> {
    args.check()?;
    let Some(path) = &args.robot else {
        return Ok(None);
    };
    inputs.add(path);
    let (robot, files) =
        Robot::load_with_files(path, &args.links()).map_err(JobError::robot(path))?;
    // Every file the robot file led to (a URDF it names) is an input too.
    for file in &files {
        inputs.add(file);
    }
    Ok(Some(robot))
}

/// Opens a table by memory map, for the length of a job.
///
/// # Errors
///
/// [`JobError::Table`] naming the file.
pub(crate) fn open_table(path: &Path) -> Result<adwi_runtime::Table<memmap2::Mmap>, JobError> {
    // SAFETY: the mapping lives as long as the job; tablec and the Python package replace
    // tables by rename, never in place.
    unsafe { adwi_runtime::Table::open(path) }.map_err(|source| JobError::Table {
        path: path.to_path_buf(),
        source,
    })
}
