//! Compiling a sample database into a cell table.
//!
//! The workspace box is cut into cubic cells. For every cell the table stores a candidate
//! list: every sample that can be among the `k` nearest admissible samples of *some*
//! target inside the cell. The runtime then only examines that list, and its answer equals
//! the brute-force reference's for every target in the grid. A sample is listed when
//!
//! - it can be within ε of a point of the cell (its distance to the cell box is at most ε),
//!   and
//! - it is not *dominated*: fewer than `k` other samples are certainly admissible
//!   everywhere in the cell (farthest distance to the box within ε) and certainly nearer
//!   (their farthest distance below its nearest distance). With configurations, the count
//!   is also taken among samples of its own configuration, since a target of that
//!   configuration sees only those. With λ or ζ thresholds, or with the joint-space screen
//!   ([`BuildOptions::joint_radius_deg`]), admissibility depends on more than the distance,
//!   no sample is certain, and nothing is pruned beyond the radius.
//!
//! Boxes are grown by [`BOX_MARGIN_MM`] and comparisons carry [`DISTANCE_SLACK_MM`], far
//! above floating-point rounding, so that a target on a cell face, or rounded into a
//! neighbouring cell, still finds every sample it needs. Each list goes into its cell's own
//! 64-byte record (the exact tier reads one cache line), or, when longer than a record
//! holds, into an overflow array.
//!
//! The served tier is then the method evaluated at every node of the grid, through the
//! list of a cell the node is a corner of — the base weights at each node, applied — once
//! for targets of unknown configuration and once per configuration the samples carry
//! ([`adwi_runtime::served`]). With [`BuildOptions::served_field`] set to
//! [`ServedField::Kriging`] (or [`ServedField::KrigingToolAxis`]), the nodes hold instead
//! kriging with a nugget of the samples' errors ([`crate::nugget_kriging`], fitted once per
//! set of samples a configuration sees; beyond a thousand samples from each node's
//! neighbours, [`crate::local_kriging`], so that it takes time and memory linear in the
//! samples): a smoother field that does not pass each sample's
//! measurement noise on. The method's nodes are missing wherever it has no admissible
//! sample, so its served field stops up to one cell short of the exact tier. The kriging is
//! defined everywhere, and its nodes are filled at every corner of a cell whose candidate
//! list holds a sample the set may use: every cell in which the exact tier can answer is
//! then served, and the served field misses no target the exact tier answers.
//!
//! Cells and nodes are processed in parallel; results are assembled in order, so the
//! bytes written do not depend on the number of threads.
//!
//! The build is split by role: [`plan()`] resolves options into a [`Plan`] before any work
//! (`plan.rs`); `candidates.rs` computes each cell's candidate list through a spatial
//! index; `nodes.rs` computes the served field's node values (the method's, or a
//! kriging's); `encode.rs` assembles the version-2 payload and its header
//! ([`compile_plan`]).

mod candidates;
pub(crate) mod encode;
pub mod merge;
mod nodes;
mod plan;

use adwi_runtime::format;
pub use adwi_runtime::format::{ServedField, Tuning};
use adwi_runtime::method::MethodParams;

pub use candidates::{BOX_MARGIN_MM, DISTANCE_SLACK_MM};
pub use encode::{compile_plan, compile_plan_serving};

/// Where a build's table will be queried, and so what it computes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Queried<'a> {
    /// Anywhere: every node and every cell's candidate list, a table to serve any target.
    Anywhere,
    /// Only at these positions (mm): by the served tier at `served`, by the exact tier at
    /// `exact`. The nodes computed are the corners of the cells the runtime blends for the
    /// `served` positions (the cell holding each, or the grid's cell nearest it outside
    /// the grid); the candidate lists, those of the cells holding a position of either
    /// kind and of the cells a computed node is a corner of (what its value is computed
    /// from). The other nodes are missing and the other lists empty. A table queried at
    /// these positions alone (an evaluation's held-out points) answers there as the full
    /// table does, for a fraction of the work. Such a table is its caller's to query, not a
    /// file to write: the build does not open it to check it, as it does a table queried
    /// anywhere, because its caller's open checks it (an evaluation opens every fold table
    /// it builds, and opening each twice was a tenth of its time).
    At {
        /// Positions the served tier is queried at, mm.
        served: &'a [[f64; 3]],
        /// Positions the exact tier is queried at, mm.
        exact: &'a [[f64; 3]],
    },
}

impl Queried<'_> {
    /// Whether the build opens the table it compiled, as the runtime will, before returning
    /// its bytes: a table queried anywhere may be written to a file, and one the runtime
    /// would refuse never is; a table queried at some positions is opened by its caller.
    pub(crate) fn opened_by_build(self) -> bool {
        matches!(self, Queried::Anywhere)
    }
}

/// The hyperparameters a kriging served field of `samples` would choose by likelihood, as
/// a build with `--served-field kriging` chooses them (of a hybrid table's residuals when
/// `model` is given), without building anything: a served-field choice searches them once
/// on all its training samples and gives them to its folds' builds
/// ([`BuildOptions::kriging_choices`]).
///
/// # Errors
///
/// A hybrid table's residuals that cannot be computed; a kriging that cannot be fitted.
pub fn kriging_choices(
    samples: &SampleSet,
    model: Option<&adwi_runtime::model::PreparedModel>,
) -> Result<Option<crate::nugget_kriging::GivenChoices>, BuildError> {
    match model {
        Some(model) => nodes::kriging_choices(
            &crate::hybrid::residual_samples(samples, model)?,
            Some(model),
        ),
        None => nodes::kriging_choices(samples, None),
    }
}
pub use plan::{
    check_options, estimated_table_bytes, human_bytes, max_covered_cells, plan,
    predicted_node_bytes, predicted_table_bytes, Plan, CELLS_PER_SPACING, MAX_CELLS,
    MAX_DERIVED_TABLE_BYTES, RADIUS_PER_SPACING,
};

use adwi_samples::SampleSet;

/// What `tablec build` is asked for; `None` fields are derived from the samples.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildOptions {
    /// The method's parameters; ε (`radius_mm`) defaults to [`RADIUS_PER_SPACING`] × the
    /// sample spacing.
    pub method: MethodParams<Option<f64>>,
    /// Cell edge, mm; default the sample spacing / [`CELLS_PER_SPACING`].
    pub cell_mm: Option<f64>,
    /// The grid's box (min, max corners, mm); default the samples' nominal bounding box
    /// grown by ε.
    pub bounds_mm: Option<([f64; 3], [f64; 3])>,
    /// The joint-space admissibility radius, degrees: when the target's joint angles are
    /// known, a sample is admissible only if every joint angle is within this of the
    /// target's (`Header::joint_radius_rad`). `None` (or 0) turns the screen off. Needs
    /// samples with joint angles.
    pub joint_radius_deg: Option<f64>,
    /// The cross-validation that chose these options, recorded in the table's header
    /// (`tablec build --tune`); `None` when they were given or defaulted.
    pub tuning: Option<Tuning>,
    /// What the served tier's nodes hold (module docs).
    pub served_field: ServedField,
    /// A kriging served field's hyperparameters, when given rather than chosen by
    /// likelihood on these samples (a served-field choice's folds reuse those of all the
    /// training samples); ignored by the method's field.
    pub kriging_choices: Option<crate::nugget_kriging::GivenChoices>,
    /// Whether a hybrid table gets a posture term ([`crate::posture`]); refused for a
    /// position-only table and with a joint screen.
    pub posture: crate::posture::Posture,
    /// The voxel edge, mm, within which samples are averaged before the table is built
    /// ([`merge`]): `None` merges only samples too many for a derived cell's size bound
    /// (the finest voxel that fits it), `Some(0.0)` never merges.
    pub merge_voxel_mm: Option<f64>,
    /// The most a table with a derived cell may take, bytes: `None` is
    /// [`MAX_DERIVED_TABLE_BYTES`], beyond which samples too many are merged where
    /// merging can bring them within it. A bound given is a promise: a build that cannot
    /// keep it (samples a spacing apart, too many to merge) is refused before any work.
    pub max_table_bytes: Option<u128>,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            method: MethodParams::paper(None),
            cell_mm: None,
            bounds_mm: None,
            joint_radius_deg: None,
            tuning: None,
            served_field: ServedField::Method,
            kriging_choices: None,
            posture: crate::posture::Posture::Off,
            merge_voxel_mm: None,
            max_table_bytes: None,
        }
    }
}

/// The weights ω1 and ω2 from what a user gave: the paper's when neither is given, and
/// `1 − ω` for the one not given, so that they sum to 1 unless both are given.
pub fn resolve_weights(w1: Option<f64>, w2: Option<f64>) -> (f64, f64) {
    let paper = MethodParams::paper(());
    match (w1, w2) {
        (None, None) => (paper.w1, paper.w2),
        (Some(w1), None) => (w1, 1.0 - w1),
        (None, Some(w2)) => (1.0 - w2, w2),
        (Some(w1), Some(w2)) => (w1, w2),
    }
}

/// Why a table could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// A parameter is out of range.
    #[error("invalid parameter: {0}")]
    Params(&'static str),
    /// ε or the cell size were not given and cannot be derived.
    #[error("cannot derive {0} from a single sample: give it explicitly")]
    CannotDerive(&'static str),
    /// The bounds are not a box.
    #[error("invalid bounds: {0}")]
    Bounds(String),
    /// The grid would be too large.
    #[error(
        "the grid would have {cells} cells of {cell_mm:.3} mm (a table of about {}), more than \
         the {max} allowed: choose a larger --cell or a smaller --bounds",
        human_bytes(*estimated_bytes)
    )]
    TooManyCells {
        /// Cells requested.
        cells: u128,
        /// The cell edge, mm.
        cell_mm: f64,
        /// The table's estimated size, bytes.
        estimated_bytes: u128,
        /// The limit.
        max: usize,
    },
    /// The table cannot be kept within the bound given.
    #[error(
        "{samples} samples do not fit a table of {}: averaged within voxels of {voxel_mm:.3} \
         mm (the coarsest tried: samples that far apart are not redundant) they are {merged} \
         samples, whose positions and errors alone take {}; give a bound above that, a \
         --merge-voxel, or fewer samples",
        human_bytes(*max_bytes),
        human_bytes(*merged_bytes)
    )]
    TableBound {
        /// The samples measured.
        samples: usize,
        /// The coarsest voxel tried, mm.
        voxel_mm: f64,
        /// The samples the coarsest voxels leave.
        merged: usize,
        /// What those samples alone take in any table, bytes: the least a bound must allow.
        merged_bytes: u128,
        /// The bound, bytes.
        max_bytes: u128,
    },
    /// A hybrid table needs the samples' joint angles, at which its model is evaluated.
    #[error("a hybrid table needs samples with joint angles (columns j1..jn)")]
    MissingJoints,
    /// A parameter, the grid or the samples are outside the range the runtime accepts.
    #[error("implausible table: {0}")]
    Implausible(format::Implausible),
    /// The samples' joint values do not fit the model's joint count.
    #[error("the samples have {samples} joint values each, the robot model {model} joints")]
    JointCount {
        /// The model's joint count.
        model: usize,
        /// The samples' joint values per sample.
        samples: usize,
    },
    /// Serialisation failed.
    #[error("cannot encode the table: {0}")]
    Encode(String),
    /// The kriging of a served field could not be fitted.
    #[error("cannot fit the kriging of the served field")]
    Kriging(#[source] crate::nugget_kriging::GpError),
    /// The nominal tool's approach axis, which a hybrid table's kriging may turn with,
    /// could not be computed at a sample's joint values.
    #[error("the nominal tool's approach axis cannot be computed at a sample's joint values")]
    ToolAxis,
    /// A kriging served field was asked of a table that has none (a joint screen).
    #[error("a kriging served field needs a served tier, which a table with a joint screen does not have")]
    KrigingWithoutServedTier,
    /// A posture term's cell lists would be longer than a query may read.
    #[error(
        "the posture term's longest cell list would hold {longest} samples, more than the \
         {max} a query may read: the samples are too dense for its support"
    )]
    PostureTooDense {
        /// The longest list of the smallest support tried, samples.
        longest: usize,
        /// The most allowed.
        max: usize,
    },
    /// A posture term was asked of a table without a kinematic model (it needs the joint
    /// values every hybrid query gives) or with a joint screen.
    #[error("a posture term needs a hybrid table (a robot file) without a joint screen")]
    PostureWithoutModel,
    /// The encoded table does not open: a bug of the compiler, never a property of the
    /// input.
    #[error("the built table does not open: please report this bug")]
    Unopenable(#[source] adwi_runtime::OpenError),
}

impl From<format::Implausible> for BuildError {
    fn from(e: format::Implausible) -> BuildError {
        BuildError::Implausible(e)
    }
}

/// What a build produced, for the CLI to report.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildReport {
    /// The plan it followed.
    pub plan: Plan,
    /// Cells whose candidate list is not empty.
    pub cells_covered: usize,
    /// Distinct candidate lists stored.
    pub distinct_lists: usize,
    /// Total entries over the distinct lists.
    pub list_entries: usize,
    /// The longest candidate list.
    pub max_list_len: usize,
    /// Mean candidate list length over covered cells.
    pub mean_list_len: f64,
    /// Table size, bytes.
    pub table_bytes: usize,
    /// Cells the served field covers (all 8 nodes answered, for targets of unknown
    /// configuration); 0 without a served tier.
    pub served_cells: usize,
    /// Node sets of the served tier (0: the exact tier alone answers).
    pub node_sets: usize,
    /// A kriging served field's hyperparameters, chosen by likelihood, per component
    /// (x, y, z, then the orientation's), of the fit serving targets of any configuration;
    /// empty when the nodes hold the method's answer.
    pub served_kriging: Vec<crate::nugget_kriging::GpChoice>,
    /// A hybrid table's posture term, when it has one.
    pub posture: Option<crate::posture::PostureReport>,
    /// A hybrid table's commanded angles the samples span, `[lowest, highest]` rad per
    /// joint (unbounded for a prismatic one): beyond them its residual fades
    /// ([`crate::hybrid::bounded_by_samples`]). Empty for a position-only table.
    pub residual_joint_range_rad: Vec<[f64; 2]>,
}

/// Plans and compiles `samples` into table bytes: [`plan`], then [`compile_plan`].
/// `progress(n)` is called as cells complete, with the number just completed (from
/// several threads).
///
/// # Errors
///
/// Parameters out of range, underivable defaults, a grid too large.
pub fn compile(
    samples: &SampleSet,
    options: &BuildOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<u8>, BuildReport), BuildError> {
    compile_serving(samples, options, Queried::Anywhere, progress)
}

/// [`compile`] computing only what a table `queried` there needs.
///
/// # Errors
///
/// As [`compile`].
pub fn compile_serving(
    samples: &SampleSet,
    options: &BuildOptions,
    queried: Queried<'_>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<u8>, BuildReport), BuildError> {
    let plan = plan(samples, options)?;
    compile_plan_serving(
        samples,
        &plan,
        None,
        samples.source_hash(),
        queried,
        progress,
    )
}

/// Samples and a build shortcut shared by the unit tests of the build's modules.
#[cfg(test)]
mod fixtures {
    use super::{compile, BuildError, BuildOptions};
    use adwi_samples::{parse_samples, ColumnMap, SampleSet};

    /// A 3 × 3 × 3 lattice of 100 mm with joint angles, plus `extra` rows.
    pub(super) fn samples(extra: &str) -> SampleSet {
        let mut csv = String::from("x,y,z,dx,dy,dz,j1,j2,j3,j4,j5,j6\n");
        for i in 0..27 {
            let p = [i % 3, (i / 3) % 3, i / 9].map(|v| 1000.0 + 100.0 * f64::from(v));
            csv += &format!("{},{},{},0.1,0.2,-0.1,{i},0,0,0,0,0\n", p[0], p[1], p[2]);
        }
        csv += extra;
        parse_samples("s.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap()
    }

    pub(super) fn build(samples: &SampleSet, options: BuildOptions) -> Result<Vec<u8>, BuildError> {
        compile(samples, &options, &|_| {}).map(|(bytes, _)| bytes)
    }

    /// A 5 × 5 × 5 lattice of 100 mm whose errors are a smooth field plus a deterministic
    /// scatter standing in for measurement noise.
    pub(super) fn noisy_lattice() -> SampleSet {
        let mut csv = String::from("x,y,z,dx,dy,dz\n");
        for i in 0..125 {
            let p = [i % 5, (i / 5) % 5, i / 25].map(|v| 1000.0 + 100.0 * f64::from(v));
            let noise = |k: i32| 0.02 * ((i * 7 + k * 13) % 11 - 5) as f64 / 5.0;
            let smooth = |a: usize| ((p[a] - 1200.0) / 300.0).sin() * 0.3;
            csv += &format!(
                "{},{},{},{},{},{}\n",
                p[0],
                p[1],
                p[2],
                smooth(0) + noise(0),
                smooth(1) + noise(1),
                smooth(2) + noise(2)
            );
        }
        parse_samples("s.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_the_papers_unless_given_and_one_implies_the_other() {
        assert_eq!(resolve_weights(None, None), (0.87, 0.13));
        assert_eq!(resolve_weights(Some(0.25), None), (0.25, 0.75));
        assert_eq!(resolve_weights(None, Some(0.25)), (0.75, 0.25));
        assert_eq!(resolve_weights(Some(0.5), Some(0.7)), (0.5, 0.7));
    }
}
