//! What can be wrong with a robot description: one error type for robot files, URDF files
//! and the robots they describe, below every module that reads or checks them.

use std::path::PathBuf;

use adwi_runtime::chain::MAX_JOINTS;

/// The deepest chain of robot files naming robot files: a TOML file naming a URDF file is
/// two; layers of TOML files (one adding a tool to another) rarely more than three.
pub const MAX_ROBOT_FILE_DEPTH: usize = 8;

/// What can be wrong with a robot file.
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// Robot files name each other in a cycle (a file naming itself, two naming each
    /// other): the files, the first named again last.
    #[error("robot files name each other in a cycle: {}", arrows(files))]
    NamingCycle {
        /// The files as they name each other, the file that closes the cycle last.
        files: Vec<PathBuf>,
    },
    /// Robot files name robot files deeper than [`MAX_ROBOT_FILE_DEPTH`].
    #[error(
        "robot files name robot files more than {} deep: {}",
        MAX_ROBOT_FILE_DEPTH,
        arrows(files)
    )]
    NamingTooDeep {
        /// The files as they name each other.
        files: Vec<PathBuf>,
    },
    /// A file named by a robot file (its `urdf` key) is not a valid robot description.
    #[error("{} names {}", file.display(), named.display())]
    InNamedFile {
        /// The robot file.
        file: PathBuf,
        /// The file it names.
        named: PathBuf,
        /// What is wrong with that file.
        #[source]
        source: Box<RobotError>,
    },
    /// The file could not be read.
    #[error("cannot read robot file {path}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML or does not have the robot file's keys.
    #[error("robot file {path} is not a valid robot description")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The TOML error, with line and column.
        #[source]
        source: crate::toml_error::TomlError,
    },
    /// The file is not a URDF file the parser reads.
    #[error("{path} is not a valid URDF file")]
    Urdf {
        /// The file.
        path: PathBuf,
        /// The parser's error.
        #[source]
        source: UrdfParseError,
    },
    /// The URDF file has no serial chain between the links asked for, or a joint this
    /// crate cannot model.
    #[error("URDF: {0}")]
    UrdfChain(String),
    /// The robot has no joint, or more than the runtime serves.
    #[error("a robot has 1 to {MAX_JOINTS} movable joints, this one {found}")]
    JointCount {
        /// How many movable joints the description has.
        found: usize,
    },
    /// A joint is described neither in MD-H nor as a chain joint, or the joints mix both.
    #[error("joint {joint}: {reason}")]
    JointStyle {
        /// Joint number, 1-based.
        joint: usize,
        /// What is wrong.
        reason: String,
    },
    /// A number is NaN or infinite.
    #[error("{field} is not a finite number")]
    NonFinite {
        /// Which value, e.g. `joint 2 a_mm`.
        field: String,
    },
    /// A number lies outside the range any robot's does ([`crate::plausible`]).
    #[error("{field}: {reason}")]
    Implausible {
        /// Which value, e.g. `joint 2 a_mm`.
        field: String,
        /// Its value and the bound it crosses.
        reason: adwi_runtime::format::Implausible,
    },
    /// A value is out of its range.
    #[error("{field}: {reason}")]
    Invalid {
        /// Which value.
        field: String,
        /// Its valid range.
        reason: String,
    },
    /// A joint's limits are empty or reversed.
    #[error("joint {joint}: limits [{lower}, {upper}] {unit} must have lower < upper")]
    EmptyLimits {
        /// Joint number, 1-based.
        joint: usize,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
        /// `deg` or `mm`.
        unit: &'static str,
    },
    /// The home posture has the wrong number of values.
    #[error("home_deg has {found} values, the robot {expected} joints")]
    HomeLength {
        /// The joint count.
        expected: usize,
        /// The values given.
        found: usize,
    },
    /// The home posture lies outside a joint's limits.
    #[error("home_deg[{index}] = {home} {unit} is outside joint {joint}'s limits [{lower}, {upper}]", index = joint - 1)]
    HomeOutsideLimits {
        /// Joint number, 1-based.
        joint: usize,
        /// The home value (deg or mm).
        home: f64,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
        /// `deg` or `mm`.
        unit: &'static str,
    },
    /// The runtime refused the chain (a rotation that is not one, an axis of zero length).
    #[error("the robot's kinematic chain is invalid")]
    Chain(#[source] adwi_runtime::chain::ChainError),
}

/// Files as they name each other, `a.toml → b.toml → a.toml`.
fn arrows(files: &[PathBuf]) -> String {
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    names.join(" → ")
}

/// The URDF parser's error, its message cut to [`UrdfParseError::MAX_CHARS`]: the parser
/// quotes attribute values whole, however long.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UrdfParseError {
    /// The parser's message, cut.
    pub message: String,
}

impl UrdfParseError {
    /// The most characters of the parser's message kept.
    pub const MAX_CHARS: usize = 300;

    pub(crate) fn new(error: &urdf_rs::UrdfError) -> UrdfParseError {
        let full = error.to_string();
        let count = full.chars().count();
        let message = if count > Self::MAX_CHARS {
            let kept: String = full.chars().take(Self::MAX_CHARS).collect();
            format!("{kept}… ({} more characters)", count - Self::MAX_CHARS)
        } else {
            full
        };
        UrdfParseError { message }
    }
}

impl std::fmt::Display for UrdfParseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for UrdfParseError {}
