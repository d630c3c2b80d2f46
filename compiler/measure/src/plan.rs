//! Which poses to measure: a set that determines the robot's kinematic parameters well
//! and covers the workspace, in an order the robot runs quickly.
//!
//! 1. **Candidates**, deterministic in the seed. Without allowed orientations, joint
//!    vectors drawn uniformly within the joint limits (the robot's sampling ranges); with
//!    them, TCP poses drawn uniformly in the boxes, turned from an allowed orientation by
//!    a random rotation up to the tolerance, and solved by inverse kinematics (the
//!    closed-form solution nearest the home posture, or the numerical one from the
//!    postures of a [`PostureTable`] nearest the pose). Kept
//!    when the nominal TCP lies in one of the boxes, within the joint limits, its
//!    orientation is allowed, and a laser tracker sees it: the TCP within the tracker's range and the tool's approach axis (z) within
//!    the sight cone about the line to the tracker. Draws are solved in parallel batches
//!    and taken in draw order. With every branch ([`Branches::All`]) each pose gives a
//!    candidate per inverse-kinematics solution within the limits; the workspace — the
//!    poses the mean prediction variance is over and the random comparison is drawn
//!    from — stays the home branch's, since the other branches are measured only for
//!    what they tell of the parameters (measuring poses the work does not use is what
//!    moves the bound below twice as many random poses, on the KR150-2).
//! 2. **Selection.** Greedy, then exchange. `Bᵢ` is the candidate's position rows of the
//!    identification Jacobian over the parameters identifiable on the whole pool, columns
//!    scaled to unit norm over the pool ([`adwi_identify::calibrate::design_jacobians`]);
//!    `M` the information of the poses chosen so far, `Σ BᵢᵀBᵢ` plus a small ridge (so
//!    that the first steps are defined), its inverse updated by the Woodbury identity, a
//!    rank-3 update per pose. With the tracker's MPE ([`TrackerSight::mpe_um`]) each
//!    block is `Bᵢ/σᵢ`, the noise of a coordinate at that distance, so that `M` is the
//!    weighted least squares' information and the variances are in mm². Each greedy step
//!    takes the candidate with the best blend of
//!    - its gain on the criterion ([`Criterion`]): by default I-optimality, how much it
//!      lowers the mean prediction variance of the TCP position over the pool,
//!      `tr(W M⁻¹)`, `W` the pool's mean `BᵢᵀBᵢ` (the pool stands for the workspace);
//!      or D-optimality, `log det(M + BᵢᵀBᵢ) − log det M`;
//!    - its coverage: the distance of its TCP to the nearest pose chosen so far (maximin).
//!
//!    Each is divided by its largest value over the remaining candidates, and the score is
//!    `(1 − w) · gain + w · coverage`, `w` the coverage weight. Then exchange passes
//!    (Fedorov's, one pose at a time): each chosen pose is taken out and the candidate the
//!    criterion gains most from put in its place, until a pass changes nothing.
//!
//!    Why I-optimality: the held-out error an identification leaves is its prediction
//!    error over the workspace, which for a model that holds is `σ² tr(W M⁻¹)` on
//!    average; D-optimality minimises the volume of the parameters' confidence ellipsoid,
//!    which weighs directions the workspace never sees. docs/measure.md, "Does planning
//!    pay?", has what each choice measurably gave.
//!
//!    **How good a plan is.** No choice of `N` poses from the pool has a mean prediction
//!    variance below [`Plan::variance_bound`], a lower bound from the convex relaxation of
//!    the choice to weights (the approximate design's optimum, `variance_bound`); the
//!    plan reports both, and their ratio bounds its efficiency. That bound is also why
//!    planned `N` poses cannot match `3N` random ones in the same workspace when it lies
//!    above the variance of `3N` random poses (about a third of `N` random poses'), as it
//!    does on the KR150-2 (docs/measure.md).
//! 3. **Order.** Nearest neighbour from the pose nearest the home posture, then 2-opt, in
//!    the largest joint travel (rad; prismatic joints in metres), which bounds the time of a
//!    move when the joints move together.
//!
//! Ties are broken by the lower candidate index, and every parallel step computes values
//! independently per candidate: the plan is the same at any thread count.

use std::fmt::Write as _;

use adwi_identify::calibrate::{design_jacobians_scaled, Parameter};
use adwi_robot::ik::PostureTable;
use adwi_robot::model::{isometry_from_parts, JointKind};
use adwi_robot::{InverseKinematics, Robot};
use adwi_runtime::format::MAX_COORDINATE_MM;
use adwi_samples::pose::{
    kuka_abc_deg_from_rotation, rotation_from_kuka_abc_deg, rotation_from_vector,
};
use nalgebra::{DMatrix, Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::field::{FieldError, FieldPrior, FieldVariance};
use crate::observability::{observability, per_display_unit, Observability};

/// The most poses a plan holds.
pub const MAX_POSES: usize = 5_000;
/// The largest candidate pool.
pub const MAX_POOL: usize = 50_000;
/// Draws solved together (in parallel) when drawing candidates.
const SOLVE_BATCH: usize = 64;
/// Draws per pool candidate before the constraints are deemed too tight: the draws stop
/// there and the pool is what was found.
pub const DRAWS_PER_CANDIDATE: usize = 200;
/// The most arithmetic the selection may take, `poses × pool × parameters²` multiply-adds
/// (about a minute on one core); larger requests are refused with their figure.
pub const MAX_SELECTION_WORK: f64 = 4e11;
/// The file's decimals (mm, degrees), as simulated sample files have them.
const DECIMALS: usize = 6;

/// A laser tracker that must see every pose.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerSight {
    /// The tracker's position, mm, base frame.
    pub position_mm: [f64; 3],
    /// Its distance range, mm: the TCP within `[min, max]` of it.
    pub range_mm: [f64; 2],
    /// The reflector's acceptance: the tool's z axis within this angle of the line to the
    /// tracker, degrees; `None` for any direction.
    pub sight_cone_deg: Option<f64>,
    /// The tracker's maximum permissible error of a point coordinate, `A + B·d` (ISO
    /// 10360-10 style: `[A µm, B µm per m]`, `d` the distance to the tracker): each pose's
    /// information is weighed by `1/σ²`, `σ = MPE/2` (data sheets state typical errors as
    /// half the MPE), so that the variances come out in mm² and a far pose counts less.
    /// `None`: every pose measured alike, variances per σ².
    pub mpe_um: Option<[f64; 2]>,
}

impl TrackerSight {
    /// The standard deviation of one measured coordinate at `position_mm`, mm (`MPE/2`);
    /// `None` without an MPE.
    pub fn sigma_mm(&self, position_mm: [f64; 3]) -> Option<f64> {
        let [a_um, b_um_per_m] = self.mpe_um?;
        let d_m = distance(position_mm, self.position_mm) / 1000.0;
        Some((a_um + b_um_per_m * d_m) / 2.0 / 1000.0)
    }
}

/// The largest MPE term accepted, µm (or µm per m): a millimetre is no laser tracker.
pub const MAX_MPE_UM: f64 = 1000.0;

/// Which inverse-kinematics solutions of a drawn pose become candidates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Branches {
    /// The one the robot works in: the closed-form solution nearest the home posture, or
    /// the posture-table solution.
    #[default]
    Home,
    /// Every branch: each closed-form solution within the limits (shoulder, elbow and
    /// wrist flips), or for robots without the closed form the posture-table solution and
    /// one reached from a posture drawn within the limits (another elbow angle of a
    /// redundant arm). The workspace, which the mean prediction variance weighs and the
    /// random poses are drawn from, stays the home branch's poses: the other branches are
    /// measured for what they tell of the parameters.
    All,
}

/// The tool orientations allowed, each within a tolerance.
#[derive(Debug, Clone, PartialEq)]
pub struct AllowedOrientations {
    /// KUKA A, B, C degrees.
    pub abc_deg: Vec<[f64; 3]>,
    /// The largest rotation from one of them, degrees.
    pub tolerance_deg: f64,
}

/// What the selection optimises (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Criterion {
    /// D-optimality: the log-determinant of the identification's information.
    D,
    /// I-optimality: the mean prediction variance of the TCP position over the workspace
    /// (the pool), what a held-out error measures.
    #[default]
    I,
    /// A-optimality on the parameters in millimetres and milliradians: the predicted mean
    /// squared parameter error, lengths and angles each averaged over their count (what
    /// the parameter error against a truth measures).
    A,
    /// I- and A-optimality together: the sum of the two criteria, each divided by its
    /// value for a design spread like the pool (so that neither's unit decides).
    Ia,
}

/// Poses measured before this plan, and what they left: the plan continues from them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Prior {
    /// The measured poses' joint values (rad; mm for prismatic joints): their information
    /// starts the design, so that the new poses add what they lack.
    pub joints: Vec<Vec<f64>>,
    /// Positions measured already (mm, base frame): a candidate's coverage is its
    /// distance to the nearest of them and of the poses taken.
    pub positions_mm: Vec<[f64; 3]>,
    /// A table's residual field: its reducible kriging variance ([`crate::field`]) takes
    /// the place of the coverage in the selection.
    pub field: Option<FieldPrior>,
}

/// The most exchange passes after the greedy selection.
pub const MAX_EXCHANGE_PASSES: usize = 20;

/// What to plan.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOptions {
    /// Boxes (min, max corners, mm, base frame): the TCP in one of them.
    pub boxes_mm: Vec<([f64; 3], [f64; 3])>,
    /// Poses to choose.
    pub count: usize,
    /// Candidates to choose from.
    pub pool: usize,
    /// Seed of the candidates.
    pub seed: u64,
    /// A tracker that must see every pose.
    pub tracker: Option<TrackerSight>,
    /// Allowed tool orientations; `None` for any.
    pub orientations: Option<AllowedOrientations>,
    /// The coverage weight `w` of the selection, 0 (D-optimal) to 1 (maximin).
    pub coverage_weight: f64,
    /// The relative pivot below which a parameter is unidentifiable (as calibrate's).
    pub rank_tolerance: f64,
    /// The criterion the selection optimises.
    pub criterion: Criterion,
    /// Exchange passes after the greedy selection (at most; a pass that changes nothing
    /// ends them), 0 to [`MAX_EXCHANGE_PASSES`].
    pub exchange_passes: usize,
    /// Poses measured already, which the plan continues; `None` for a first plan.
    pub prior: Option<Prior>,
    /// Which inverse-kinematics branches become candidates (with allowed orientations).
    pub branches: Branches,
}

/// Why a plan cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// An option out of range, named.
    #[error("{name}: {reason}")]
    Option {
        /// The option.
        name: &'static str,
        /// Why.
        reason: String,
    },
    /// The candidates found fall short of the poses asked for.
    #[error("{found} reachable candidates in {draws} draws, fewer than the {count} poses asked for: widen the box, the range, the cone or the orientation tolerance, or ask for fewer poses")]
    TooFewCandidates {
        /// Candidates found.
        found: usize,
        /// Draws made.
        draws: usize,
        /// Poses asked for.
        count: usize,
    },
    /// The identification's Jacobian cannot be formed.
    #[error(transparent)]
    Jacobian(#[from] Box<adwi_identify::calibrate::CalibrateError>),
    /// The table's residual field's variance cannot be computed.
    #[error(transparent)]
    Field(#[from] FieldError),
}

/// One planned pose.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedPose {
    /// Joint values, rad (mm when prismatic), rounded to the file's decimals.
    pub joints: Vec<f64>,
    /// The nominal TCP position at those joints, mm.
    pub position_mm: [f64; 3],
    /// The nominal TCP orientation, KUKA A, B, C degrees.
    pub abc_deg: [f64; 3],
    /// Whether the pose is of the workspace (the home branch, [`Branches`]) rather than
    /// another branch measured for the parameters' sake.
    pub workspace: bool,
}

/// A plan and what it achieves.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The poses, in the order to measure them.
    pub poses: Vec<PlannedPose>,
    /// The parameters identifiable on the pool, which the selection weighs.
    pub parameters: Vec<Parameter>,
    /// Candidates in the pool.
    pub pool: usize,
    /// Draws made (joint vectors, or poses solved by inverse kinematics).
    pub draws: usize,
    /// `log det` of the chosen poses' information (scaled parameters, with the ridge).
    pub log_det: f64,
    /// The chosen poses' mean prediction variance of the TCP position over the pool, in
    /// units of the noise variance of one measured coordinate (`tr(W M⁻¹)`, module docs):
    /// the identified model's mean squared position error at the candidates is this
    /// times σ², if the model is right.
    pub mean_variance: f64,
    /// A lower bound on [`Self::mean_variance`] for any choice of as many poses from the
    /// pool (module docs, "How good a plan is").
    pub variance_bound: f64,
    /// The smallest distance between two chosen poses' TCPs, mm; `None` for a single pose.
    pub min_distance_mm: Option<f64>,
    /// The path's joint travel, the sum of the largest joint move of each step (rad).
    pub path_travel: f64,
    /// The criterion's value for the chosen poses (per σ²; for D-optimality, the mean
    /// prediction variance).
    pub criterion_value: f64,
    /// A lower bound on it for any choice of as many poses from the pool: the
    /// efficiency is at least `criterion_bound / criterion_value`.
    pub criterion_bound: f64,
    /// The chosen poses' figures (with the poses measured before, when the plan continues
    /// them).
    pub planned: SetFigures,
    /// The same figures for random poses drawn from the same workspace apart from the
    /// pool (never the candidates themselves): as many as planned, then twice as many.
    /// Empty when the workspace did not yield that many.
    pub random: Vec<SetFigures>,
    /// The table's residual field's variance, mean over the candidates (mm², summed over
    /// x, y, z): before this plan, after the planned poses, after the first random set;
    /// `None` without a table.
    pub field_variance_mm2: Option<[f64; 3]>,
    /// The smallest and largest standard deviation of a measured coordinate over the
    /// candidates (mm) when the tracker's MPE weighs them: the variances are then in mm²
    /// (and mm², mrad² for the parameters) rather than per σ².
    pub tracker_sigma_mm: Option<[f64; 2]>,
    /// Candidates of the workspace's branch (all of them unless every branch is drawn).
    pub workspace_candidates: usize,
    /// Planned poses of another branch than the workspace's.
    pub other_branches: usize,
}

/// What a set of poses achieves, in the units of one measured coordinate's noise σ.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SetFigures {
    /// Poses in the set.
    pub poses: usize,
    /// Mean prediction variance of the TCP position over the pool, per σ².
    pub mean_variance: f64,
    /// Predicted mean squared parameter error, lengths (mm²) and angles (mrad²) each
    /// averaged over their count and added, per σ² (mm²).
    pub parameter_variance: f64,
    /// The observability indices ([`crate::observability`]); `None` when a parameter is
    /// undetermined.
    pub observability: Option<Observability>,
}

fn option(name: &'static str, reason: impl Into<String>) -> PlanError {
    PlanError::Option {
        name,
        reason: reason.into(),
    }
}

/// Checks the options and sizes the work before any: the counts, the boxes, the tracker,
/// the orientations ([`check_options`]), the measured poses, and the selection's
/// arithmetic against [`MAX_SELECTION_WORK`].
///
/// # Errors
///
/// [`PlanError::Option`] naming the option and the figure.
pub fn check(robot: &Robot, options: &PlanOptions) -> Result<(), PlanError> {
    check_options(options)?;
    check_sized(robot, options)
}

/// The checks that need no robot: counts, boxes, tracker, orientations, weights; run
/// before any file is read.
///
/// # Errors
///
/// [`PlanError::Option`] naming the option and the figure.
pub fn check_options(options: &PlanOptions) -> Result<(), PlanError> {
    let finite3 = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
    // Within a kilometre of the base, as a table's coordinates: a box's extents and
    // volume then stay finite (a box of ±1e200 mm has an infinite volume to draw from).
    let plausible3 = |v: &[f64; 3]| v.iter().all(|x| x.abs() <= MAX_COORDINATE_MM);
    if !(1..=MAX_POSES).contains(&options.count) {
        return Err(option(
            "count",
            format!("{} poses: give 1 to {MAX_POSES}", options.count),
        ));
    }
    if options.pool < options.count || options.pool > MAX_POOL {
        return Err(option(
            "pool",
            format!(
                "{} candidates: give at least the count ({}) and at most {MAX_POOL}",
                options.pool, options.count
            ),
        ));
    }
    if options.boxes_mm.is_empty() {
        return Err(option(
            "box",
            "give at least one box (--min and --max, or --box)",
        ));
    }
    for (min, max) in &options.boxes_mm {
        if !(finite3(min) && finite3(max) && (0..3).all(|a| min[a] < max[a])) {
            return Err(option(
                "box",
                format!("{min:?} to {max:?} mm: each minimum must be below its maximum, finite"),
            ));
        }
        if !(plausible3(min) && plausible3(max)) {
            return Err(option(
                "box",
                format!(
                    "{min:?} to {max:?} mm: a corner is more than {MAX_COORDINATE_MM:e} mm \
                     from the base on an axis; give the robot's workspace in mm"
                ),
            ));
        }
    }
    if let Some(t) = &options.tracker {
        let [near, far] = t.range_mm;
        if finite3(&t.position_mm) && !plausible3(&t.position_mm) {
            return Err(option(
                "tracker",
                format!(
                    "{:?} mm: more than {MAX_COORDINATE_MM:e} mm from the base on an axis",
                    t.position_mm
                ),
            ));
        }
        if !(finite3(&t.position_mm)
            && near.is_finite()
            && far.is_finite()
            && (0.0..far).contains(&near))
        {
            return Err(option(
                "tracker_range",
                format!("{near},{far} mm: give 0 ≤ MIN < MAX, finite"),
            ));
        }
        if let Some(cone) = t.sight_cone_deg {
            if !(cone > 0.0 && cone <= 180.0) {
                return Err(option(
                    "sight_cone_deg",
                    format!("{cone}°: give an angle in (0, 180]"),
                ));
            }
        }
        if let Some([a, b]) = t.mpe_um {
            let term = |v: f64| v.is_finite() && (0.0..=MAX_MPE_UM).contains(&v);
            if !(term(a) && term(b) && a > 0.0) {
                return Err(option(
                    "tracker_mpe_um",
                    format!(
                        "{a},{b}: give A > 0 µm and B ≥ 0 µm per m, each at most {MAX_MPE_UM} \
                         (the MPE A + B·d of a point coordinate)"
                    ),
                ));
            }
        }
    }
    if options.branches == Branches::All && options.orientations.is_none() {
        return Err(option(
            "branches",
            "every branch needs allowed orientations (--abc): joint values drawn within the \
             limits take every branch already",
        ));
    }
    if let Some(o) = &options.orientations {
        if o.abc_deg.is_empty() || !o.abc_deg.iter().all(finite3) {
            return Err(option("abc", "give finite A,B,C orientations"));
        }
        if !(o.tolerance_deg > 0.0 && o.tolerance_deg <= 180.0) {
            return Err(option(
                "orientation_tolerance",
                format!("{}°: give an angle in (0, 180]", o.tolerance_deg),
            ));
        }
    }
    if !(0.0..=1.0).contains(&options.coverage_weight) {
        return Err(option(
            "coverage",
            format!("{}: give a weight from 0 to 1", options.coverage_weight),
        ));
    }
    if !(options.rank_tolerance > 0.0 && options.rank_tolerance < 1.0) {
        return Err(option(
            "rank_tol",
            format!(
                "{}: give a relative pivot between 0 and 1",
                options.rank_tolerance
            ),
        ));
    }
    if options.exchange_passes > MAX_EXCHANGE_PASSES {
        return Err(option(
            "exchange_passes",
            format!(
                "{} passes: give 0 to {MAX_EXCHANGE_PASSES}",
                options.exchange_passes
            ),
        ));
    }
    Ok(())
}

/// The checks that need the robot: the measured poses' joints, and the work.
fn check_sized(robot: &Robot, options: &PlanOptions) -> Result<(), PlanError> {
    let finite3 = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
    if let Some(prior) = &options.prior {
        let n = robot.joint_count();
        if let Some(q) = prior.joints.iter().find(|q| q.len() != n) {
            return Err(option(
                "measured",
                format!(
                    "a measured pose has {} joint values, the robot {n}",
                    q.len()
                ),
            ));
        }
        if !prior.joints.iter().flatten().all(|v| v.is_finite())
            || !prior.positions_mm.iter().all(finite3)
        {
            return Err(option("measured", "a measured pose is not finite"));
        }
        if prior.joints.len() > MAX_POOL || prior.positions_mm.len() > MAX_POOL {
            return Err(option(
                "measured",
                format!("more than {MAX_POOL} poses measured already"),
            ));
        }
    }
    // Each greedy step and each exchange of a pose weighs every candidate.
    let p = Parameter::all_of(robot).len() as f64;
    let rounds = 1.0 + options.exchange_passes as f64;
    let work = rounds * options.count as f64 * options.pool as f64 * p * p;
    if work > MAX_SELECTION_WORK {
        return Err(option(
            "count",
            format!(
                "{} poses from {} candidates over {p} parameters, {rounds} rounds (greedy and \
                 exchange passes), is {work:.1e} multiply-adds, more than \
                 {MAX_SELECTION_WORK:.0e} (about a minute on one core): ask for fewer poses, \
                 a smaller pool or fewer exchange passes",
                options.count, options.pool
            ),
        ));
    }
    Ok(())
}

/// A joint value as the file writes it: degrees (mm) rounded to [`DECIMALS`], and back.
fn as_written(robot: &Robot, q: &[f64]) -> Vec<f64> {
    let scale = 10f64.powi(DECIMALS as i32);
    q.iter()
        .enumerate()
        .map(|(i, &v)| match robot.joint_kind(i) {
            JointKind::Revolute => ((v.to_degrees() * scale).round() / scale).to_radians(),
            JointKind::Prismatic => (v * scale).round() / scale,
        })
        .collect()
}

/// Whether the pose at `q` meets the plan's constraints; its TCP position when it does.
fn admissible(robot: &Robot, options: &PlanOptions, q: &[f64]) -> Option<PlannedPose> {
    let pose = robot.tcp_pose(q);
    let p = pose.translation.vector;
    let position_mm = [p.x, p.y, p.z];
    let inside = options
        .boxes_mm
        .iter()
        .any(|(min, max)| (0..3).all(|a| (min[a]..=max[a]).contains(&position_mm[a])));
    if !inside || !robot.within_limits(q) {
        return None;
    }
    let rotation = pose.rotation.to_rotation_matrix();
    if let Some(t) = &options.tracker {
        let to_tracker = Vector3::from(t.position_mm) - p;
        let range = to_tracker.norm();
        if !(t.range_mm[0]..=t.range_mm[1]).contains(&range) {
            return None;
        }
        if let Some(cone) = t.sight_cone_deg {
            let axis = rotation * Vector3::z();
            if range == 0.0 || axis.angle(&to_tracker).to_degrees() > cone {
                return None;
            }
        }
    }
    if let Some(o) = &options.orientations {
        let allowed = o.abc_deg.iter().any(|abc| {
            let r = rotation_from_kuka_abc_deg(*abc);
            r.angle_to(&rotation).to_degrees() <= o.tolerance_deg
        });
        if !allowed {
            return None;
        }
    }
    Some(PlannedPose {
        joints: q.to_vec(),
        position_mm,
        abc_deg: kuka_abc_deg_from_rotation(&rotation),
        workspace: true,
    })
}

/// The candidate pool: joint vectors drawn within the sampling ranges, as written to the
/// file, kept when admissible; at most `pool`, after at most `pool ×`
/// [`DRAWS_PER_CANDIDATE`] draws. `advance` is told of each candidate found.
///
/// # Errors
///
/// [`PlanError::TooFewCandidates`] when fewer than `count` are found.
pub fn candidates(
    robot: &Robot,
    options: &PlanOptions,
    advance: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<PlannedPose>, usize), PlanError> {
    candidates_from(robot, options, 0, advance)
}

/// [`candidates`] from stream `stream` of the seed: stream 0 is the pool, another stream
/// draws other poses from the same workspace.
///
/// # Errors
///
/// As [`candidates`].
pub fn candidates_from(
    robot: &Robot,
    options: &PlanOptions,
    stream: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<PlannedPose>, usize), PlanError> {
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    rng.set_stream(stream);
    let sampler = Sampler::new(robot, options);
    let max_draws = options.pool.saturating_mul(DRAWS_PER_CANDIDATE);
    let mut found = Vec::with_capacity(options.pool);
    let mut draws = 0;
    while found.len() < options.pool && draws < max_draws {
        let batch = (options.pool - found.len())
            .clamp(1, SOLVE_BATCH)
            .min(max_draws - draws);
        let drawn: Vec<Draw> = (0..batch).map(|_| sampler.draw(&mut rng)).collect();
        let solved: Vec<Vec<PlannedPose>> = drawn.par_iter().map(|d| sampler.solve(d)).collect();
        'draws: for poses in solved {
            draws += 1;
            for pose in poses {
                found.push(pose);
                advance(1);
                if found.len() == options.pool {
                    break 'draws;
                }
            }
        }
    }
    if found.len() < options.count {
        return Err(PlanError::TooFewCandidates {
            found: found.len(),
            draws,
            count: options.count,
        });
    }
    Ok((found, draws))
}

/// How a candidate's pose is solved: in closed form (the solution nearest home) or,
/// without it, from the drawn postures nearest the pose (a fraction of a millisecond,
/// where the posture nearest home took tens): any posture within the limits does for a
/// candidate.
enum Solver {
    ClosedForm(Box<InverseKinematics>),
    Table(PostureTable),
}

/// A draw: joint values, or a pose to solve. With every branch, a robot without the
/// closed form also gets a posture drawn within the limits to start from (drawn in
/// order with the pose, so that the pool is the same at any thread count).
enum Draw {
    Joints(Vec<f64>),
    Pose(nalgebra::Isometry3<f64>, Option<Vec<f64>>),
}

/// The candidates' sampling: what is drawn from the seed, and how a draw becomes poses.
/// The draws are made in order from the seed; batches of them are solved in parallel and
/// taken in draw order, so the pool is the same at any thread count (and the same as
/// drawing and solving one at a time).
struct Sampler<'a> {
    robot: &'a Robot,
    options: &'a PlanOptions,
    /// Each joint's sampling range.
    ranges: Vec<[f64; 2]>,
    /// Each box's volume, mm³, and their sum: a pose is drawn in a box by its volume.
    volumes: Vec<f64>,
    total_volume: f64,
    /// The solver of drawn poses (none when joints are drawn).
    solver: Option<Solver>,
    every_branch: bool,
}

impl<'a> Sampler<'a> {
    fn new(robot: &'a Robot, options: &'a PlanOptions) -> Sampler<'a> {
        let ranges: Vec<[f64; 2]> = (0..robot.joint_count())
            .map(|i| robot.sampling_range(i))
            .collect();
        let solver = options
            .orientations
            .as_ref()
            .map(|_| match InverseKinematics::new(robot) {
                Ok(ik) => Solver::ClosedForm(Box::new(ik)),
                Err(_) => Solver::Table(PostureTable::new(robot)),
            });
        let volumes: Vec<f64> = options
            .boxes_mm
            .iter()
            .map(|(min, max)| (0..3).map(|a| max[a] - min[a]).product())
            .collect();
        let total_volume: f64 = volumes.iter().sum();
        Sampler {
            robot,
            options,
            ranges,
            volumes,
            total_volume,
            solver,
            every_branch: options.branches == Branches::All,
        }
    }

    /// Joint values drawn within the sampling ranges.
    fn joints(&self, rng: &mut ChaCha8Rng) -> Vec<f64> {
        self.ranges
            .iter()
            .map(|&[lo, hi]| rng.gen_range(lo..=hi))
            .collect()
    }

    /// The next draw.
    fn draw(&self, rng: &mut ChaCha8Rng) -> Draw {
        let Some(allowed) = &self.options.orientations else {
            return Draw::Joints(self.joints(rng));
        };
        // A pose in the boxes (each by its volume), turned from an allowed orientation by
        // up to the tolerance.
        let mut pick = rng.gen_range(0.0..self.total_volume);
        let mut k = 0;
        while k + 1 < self.volumes.len() && pick >= self.volumes[k] {
            pick -= self.volumes[k];
            k += 1;
        }
        let (min, max) = self.options.boxes_mm[k];
        let position: [f64; 3] = std::array::from_fn(|a| rng.gen_range(min[a]..=max[a]));
        let abc = allowed.abc_deg[rng.gen_range(0..allowed.abc_deg.len())];
        let z: f64 = rng.gen_range(-1.0..=1.0);
        let azimuth: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let angle = rng.gen_range(0.0..=allowed.tolerance_deg).to_radians();
        let turn = [r * azimuth.cos(), r * azimuth.sin(), z].map(|v| v * angle);
        let rotation = rotation_from_vector(turn) * rotation_from_kuka_abc_deg(abc);
        let numerical = matches!(self.solver, Some(Solver::Table(_)));
        let start = (self.every_branch && numerical).then(|| self.joints(rng));
        Draw::Pose(isometry_from_parts(position, &rotation), start)
    }

    /// The admissible candidates of a draw: its postures (the home branch first, then the
    /// others with every branch), as written to the file, within the constraints.
    fn solve(&self, d: &Draw) -> Vec<PlannedPose> {
        let (robot, options) = (self.robot, self.options);
        self.postures(d)
            .into_iter()
            .filter_map(|(q, workspace)| {
                let mut pose = admissible(robot, options, &as_written(robot, &q))?;
                pose.workspace = workspace;
                Some(pose)
            })
            .collect()
    }

    /// A draw's postures, each with whether it is the home branch (`workspace`).
    fn postures(&self, d: &Draw) -> Vec<(Vec<f64>, bool)> {
        let robot = self.robot;
        let (pose, start) = match d {
            Draw::Joints(q) => return vec![(q.clone(), true)],
            Draw::Pose(pose, start) => (pose, start),
        };
        match self.solver.as_ref() {
            None => Vec::new(),
            Some(Solver::ClosedForm(ik)) => {
                let all = ik.solve(pose);
                let home = nearest_home(robot, all.iter().map(|s| s.q_rad.to_vec()));
                let mut out: Vec<(Vec<f64>, bool)> =
                    home.iter().map(|q| (q.clone(), true)).collect();
                if self.every_branch {
                    out.extend(
                        all.into_iter()
                            .map(|s| s.q_rad.to_vec())
                            .filter(|q| Some(q) != home.as_ref())
                            .map(|q| (q, false)),
                    );
                }
                out
            }
            Some(Solver::Table(table)) => {
                let home = table.solve(robot, pose);
                let mut out: Vec<(Vec<f64>, bool)> =
                    home.iter().map(|q| (q.clone(), true)).collect();
                let other = start
                    .as_ref()
                    .and_then(|s| adwi_robot::ik::solve_from(robot, pose, s));
                if let Some(q) = other {
                    // Another posture, not the home one found again.
                    let apart = home.as_ref().is_none_or(|h| travel(robot, h, &q) > 1e-3);
                    if apart {
                        out.push((q, false));
                    }
                }
                out
            }
        }
    }
}

/// Of closed-form solutions, the one nearest the home posture, as `tablec simulate`
/// chooses.
fn nearest_home(robot: &Robot, solutions: impl Iterator<Item = Vec<f64>>) -> Option<Vec<f64>> {
    let home = robot.home();
    let distance = |q: &[f64]| -> f64 { q.iter().zip(home).map(|(a, b)| (a - b).powi(2)).sum() };
    solutions.min_by(|a, b| distance(a).total_cmp(&distance(b)))
}

/// The information of a set of poses: `ridge · I + Σ BᵢᵀBᵢ`.
fn information(blocks: &[&DMatrix<f64>], k: usize, ridge: f64) -> DMatrix<f64> {
    with_blocks(DMatrix::identity(k, k) * ridge, blocks)
}

/// `base + Σ BᵢᵀBᵢ`.
fn with_blocks(mut base: DMatrix<f64>, blocks: &[&DMatrix<f64>]) -> DMatrix<f64> {
    for b in blocks {
        base += b.transpose() * *b;
    }
    base
}

/// `log det` of a symmetric positive definite matrix, by Cholesky.
fn log_det(m: &DMatrix<f64>) -> f64 {
    match m.clone().cholesky() {
        Some(c) => 2.0 * c.l().diagonal().iter().map(|d| d.ln()).sum::<f64>(),
        None => f64::NEG_INFINITY,
    }
}

/// `log det(I₃ + B M⁻¹ Bᵀ)`, the gain of adding block `B` to information `M`: the
/// reference of [`Design::gains`] for D-optimality.
#[cfg(test)]
fn gain(b: &DMatrix<f64>, m_inv: &DMatrix<f64>) -> f64 {
    let s: DMatrix<f64> = DMatrix::identity(3, 3) + b * m_inv * b.transpose();
    s.determinant().max(f64::MIN_POSITIVE).ln()
}

/// `tr(L M⁻¹) − tr(L (M + BᵀB)⁻¹) = tr((I₃ + B M⁻¹ Bᵀ)⁻¹ B G Bᵀ)` with `G = M⁻¹ L M⁻¹`:
/// how much adding block `B` lowers a linear criterion `tr(L M⁻¹)` (Woodbury; `L = W` is
/// the mean prediction variance): the reference of [`Design::gains`] for the linear
/// criteria.
#[cfg(test)]
fn variance_gain(b: &DMatrix<f64>, m_inv: &DMatrix<f64>, g: &DMatrix<f64>) -> f64 {
    let bm = b * m_inv;
    let s: DMatrix<f64> = DMatrix::identity(3, 3) + &bm * b.transpose();
    let t: DMatrix<f64> = b * g * b.transpose();
    match s.cholesky() {
        Some(c) => c.solve(&t).trace().max(0.0),
        None => 0.0,
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (Vector3::from(a) - Vector3::from(b)).norm()
}

/// `M⁻¹` updated for adding (`sign` 1) or removing (`sign` −1) block `B`, by Woodbury:
/// `(M ± BᵀB)⁻¹ = M⁻¹ ∓ M⁻¹Bᵀ (I ± B M⁻¹ Bᵀ)⁻¹ B M⁻¹`. `None` when the 3 × 3 system is
/// singular (a removal that would leave `M` singular).
fn updated(m_inv: &DMatrix<f64>, b: &DMatrix<f64>, sign: f64) -> Option<DMatrix<f64>> {
    let mb = m_inv * b.transpose();
    let s: DMatrix<f64> = DMatrix::identity(3, 3) * sign + b * &mb;
    let s_inv = s.try_inverse()?;
    Some(m_inv - &mb * s_inv * mb.transpose())
}

/// What a criterion needs of the current design: `M⁻¹`, and for a linear criterion
/// `tr(L M⁻¹)` the matrix `G = M⁻¹ L M⁻¹`; and every candidate's block stacked (3 rows
/// each), so that the gains of all candidates are a few matrix products rather than one
/// small product each.
struct Design<'a> {
    criterion: Criterion,
    /// `L` of the linear criterion (unused for D-optimality).
    weight: &'a DMatrix<f64>,
    stacked: &'a DMatrix<f64>,
    m_inv: DMatrix<f64>,
    g: DMatrix<f64>,
}

/// Candidates per parallel chunk of the gains: each chunk's products are computed alone,
/// so the gains are the same at any thread count.
const GAIN_CHUNK: usize = 256;

impl<'a> Design<'a> {
    fn new(
        criterion: Criterion,
        weight: &'a DMatrix<f64>,
        stacked: &'a DMatrix<f64>,
        m_inv: DMatrix<f64>,
    ) -> Self {
        let mut d = Design {
            criterion,
            weight,
            stacked,
            m_inv,
            g: DMatrix::zeros(0, 0),
        };
        d.refresh();
        d
    }

    fn linear(&self) -> bool {
        self.criterion != Criterion::D
    }

    fn refresh(&mut self) {
        if self.linear() {
            self.g = &self.m_inv * self.weight * &self.m_inv;
        }
    }

    /// Every candidate's gain against the current design: [`gain`] or
    /// [`variance_gain`], computed from the stacked products.
    fn gains(&self) -> Vec<f64> {
        let n = self.stacked.nrows() / 3;
        let chunks: Vec<usize> = (0..n).step_by(GAIN_CHUNK).collect();
        chunks
            .par_iter()
            .flat_map_iter(|&start| {
                let len = GAIN_CHUNK.min(n - start);
                let b = self.stacked.rows(3 * start, 3 * len);
                let bm = b * &self.m_inv;
                let bg = self.linear().then(|| b * &self.g);
                (0..len)
                    .map(|i| {
                        let rows = |m: &DMatrix<f64>| {
                            Matrix3::from_fn(|r, c| m.row(3 * i + r).dot(&b.row(3 * i + c)))
                        };
                        let s = Matrix3::identity() + rows(&bm);
                        match &bg {
                            None => s.determinant().max(f64::MIN_POSITIVE).ln(),
                            Some(bg) => s
                                .cholesky()
                                .map_or(0.0, |c| c.solve(&rows(bg)).trace().max(0.0)),
                        }
                    })
                    .collect::<Vec<f64>>()
            })
            .collect()
    }

    /// Adds (`sign` 1) or removes (`sign` −1) a block; `false` when that is singular.
    fn update(&mut self, b: &DMatrix<f64>, sign: f64) -> bool {
        match updated(&self.m_inv, b, sign) {
            Some(m) => {
                self.m_inv = m;
                self.refresh();
                true
            }
            None => false,
        }
    }
}

/// What [`select`] chose and what it achieves.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Indices into the candidates: greedy ones in the order chosen, exchanged ones in the
    /// place of the pose they replaced.
    pub chosen: Vec<usize>,
    /// The parameters weighed.
    pub parameters: Vec<Parameter>,
    /// [`Plan::log_det`].
    pub log_det: f64,
    /// [`Plan::mean_variance`].
    pub mean_variance: f64,
    /// [`Plan::variance_bound`].
    pub variance_bound: f64,
    /// [`Plan::criterion_value`].
    pub criterion_value: f64,
    /// [`Plan::criterion_bound`].
    pub criterion_bound: f64,
}

/// Iterations of the multiplicative algorithm behind [`Plan::variance_bound`].
const BOUND_ITERATIONS: usize = 100;

/// A lower bound on `tr(L M⁻¹)` for any `count` poses of the pool added to `base` (the
/// ridge, and the information of poses measured before) (module docs, "How good a plan
/// is"): the relaxation to weights `ξᵢ ≥ 0`, `Σ ξᵢ = 1`, with information `count · M(ξ)`,
/// `M(ξ) = Σ ξᵢ BᵢᵀBᵢ + base / count`, is convex in `ξ`, so for any `ξ` its optimum is at
/// least `φ(ξ) + Σ ξⱼ dⱼ(ξ) − max_i dᵢ(ξ)` (the tangent plane), `φ = tr(L M(ξ)⁻¹)`,
/// `−dᵢ = −tr(Bᵢ M(ξ)⁻¹ L M(ξ)⁻¹ Bᵢᵀ)` the derivative in `ξᵢ`; `ξ` is improved by the
/// multiplicative algorithm `ξᵢ ← ξᵢ dᵢ / Σ ξⱼ dⱼ` to make the bound tight.
fn variance_bound(
    stacked: &DMatrix<f64>,
    weight: &DMatrix<f64>,
    count: usize,
    base: &DMatrix<f64>,
) -> f64 {
    let n = stacked.nrows() / 3;
    let mut xi = vec![1.0 / n as f64; n];
    let mut best = 0.0_f64;
    for _ in 0..BOUND_ITERATIONS {
        let mut weighted = stacked.clone();
        for (i, w) in xi.iter().enumerate() {
            weighted.rows_mut(3 * i, 3).scale_mut(*w);
        }
        let m = stacked.transpose() * weighted + base / count as f64;
        let Some(m_inv) = m.try_inverse() else {
            break;
        };
        let phi = (weight * &m_inv).trace();
        let g = &m_inv * weight * &m_inv;
        let bg = stacked * g;
        let d: Vec<f64> = (0..n)
            .map(|i| {
                (0..3)
                    .map(|r| bg.row(3 * i + r).dot(&stacked.row(3 * i + r)))
                    .sum()
            })
            .collect();
        let largest = d.iter().copied().fold(0.0, f64::max);
        // Σ ξᵢ dᵢ is φ less the base's share, which the derivative leaves out.
        let mean: f64 = xi.iter().zip(&d).map(|(x, di)| x * di).sum();
        best = best.max(phi + mean - largest);
        if !(phi > 0.0 && phi.is_finite()) {
            break;
        }
        let total_d: f64 = mean;
        if total_d.is_nan() || total_d <= 0.0 {
            break;
        }
        for (x, di) in xi.iter_mut().zip(&d) {
            *x *= di / total_d;
        }
        let total: f64 = xi.iter().sum();
        xi.iter_mut().for_each(|x| *x /= total);
    }
    best / count as f64
}

/// A second lower bound on `tr(L M⁻¹)` for any `count` distinct poses of the pool added
/// to `base`: the relaxation with each candidate's weight at most `1 / count` (every
/// choice of distinct poses is one of its points) is convex too, and its tangent plane at
/// the chosen poses' weights (`1 / count` each) bounds it below by `φ + mean over the
/// chosen of dᵢ − mean of the count largest dᵢ` ([`variance_bound`]'s notation): tight
/// when no exchange of one pose helps, where the uncapped bound leaves the gap of weights
/// no set of distinct poses can take.
fn capped_bound(
    stacked: &DMatrix<f64>,
    weight: &DMatrix<f64>,
    base: &DMatrix<f64>,
    chosen: &[usize],
) -> f64 {
    let count = chosen.len();
    let mut m = base.clone();
    for &i in chosen {
        let b = stacked.rows(3 * i, 3);
        m += b.transpose() * b;
    }
    let Some(m_inv) = m.try_inverse() else {
        return 0.0;
    };
    // In the weights' scale: M(ξ) is that information divided by the count.
    let m_inv = m_inv * count as f64;
    let phi = (weight * &m_inv).trace();
    let g = &m_inv * weight * &m_inv;
    let bg = stacked * g;
    let mut d: Vec<f64> = (0..stacked.nrows() / 3)
        .map(|i| {
            (0..3)
                .map(|r| bg.row(3 * i + r).dot(&stacked.row(3 * i + r)))
                .sum()
        })
        .collect();
    let at: f64 = chosen.iter().map(|&i| d[i]).sum::<f64>() / count as f64;
    d.sort_by(|a, b| b.total_cmp(a));
    let top: f64 = d.iter().take(count).sum::<f64>() / count as f64;
    ((phi + at - top) / count as f64).max(0.0)
}

/// The identification's Jacobians of the pool, of further poses (the random comparison)
/// and of the poses measured before, over the parameters identifiable on all of them
/// together, in one scaling; and what the criteria weigh.
pub struct Prepared {
    /// The parameters, in the blocks' column order.
    pub parameters: Vec<Parameter>,
    /// The pool's blocks.
    pub pool: Vec<DMatrix<f64>>,
    /// The further poses' blocks.
    pub extra: Vec<DMatrix<f64>>,
    /// The measured poses' blocks.
    pub prior: Vec<DMatrix<f64>>,
    /// Per column, the factor from a scaled block's column to mm per mm or per mrad.
    pub display: Vec<f64>,
    /// The ridge of the information.
    pub ridge: f64,
    /// `W`: the pool's mean information (the mean prediction variance's weight).
    pub workspace: DMatrix<f64>,
    /// `L_A`: the parameters' variances in mm² and mrad², each group by its count.
    pub parameter_weight: DMatrix<f64>,
    /// The information a plan starts from: the ridge and the measured poses'.
    pub base: DMatrix<f64>,
    /// Each block's weight `1/σ²` (mm⁻²) from the tracker's MPE, pool, further poses and
    /// measured poses in turn; empty without one (every weight 1, variances per σ²).
    pub weights: Vec<f64>,
}

impl Prepared {
    /// The Jacobians and weights for `pool`, `extra` and `prior` joint vectors.
    ///
    /// # Errors
    ///
    /// [`PlanError::Jacobian`] when the identification's Jacobian cannot be formed.
    pub fn new(
        robot: &Robot,
        pool: &[PlannedPose],
        extra: &[PlannedPose],
        prior: &[Vec<f64>],
        rank_tolerance: f64,
        tracker: Option<&TrackerSight>,
    ) -> Result<Prepared, PlanError> {
        let joints: Vec<Vec<f64>> = pool
            .iter()
            .chain(extra)
            .map(|c| c.joints.clone())
            .chain(prior.iter().cloned())
            .collect();
        let (parameters, mut blocks, scales) =
            design_jacobians_scaled(robot, &joints, rank_tolerance).map_err(Box::new)?;
        let k = parameters.len();
        let mut prior_blocks = blocks.split_off(pool.len() + extra.len());
        let mut extra_blocks = blocks.split_off(pool.len());
        // Columns have unit norm over all the poses: one pose holds about 1/poses of each;
        // the ridge is a thousandth of that, so that the first poses are chosen by what
        // they add.
        let mut ridge = 1e-3 / joints.len() as f64;
        // The workspace is the home branch's candidates: other branches are measured, not
        // worked at. (Without other branches, every candidate.)
        let at_work: Vec<&DMatrix<f64>> = blocks
            .iter()
            .zip(pool)
            .filter(|(_, c)| c.workspace)
            .map(|(b, _)| b)
            .collect();
        let workspace = information(&at_work, k, 0.0) / at_work.len().max(1) as f64;
        // The tracker's uncertainty: each block scaled by 1/σ, its information by 1/σ²; the
        // ridge by the pool's mean weight, so that it stays as small beside the poses.
        let positions: Vec<[f64; 3]> = pool
            .iter()
            .chain(extra)
            .map(|c| c.position_mm)
            .chain(prior.iter().map(|q| {
                let p = robot.tcp_pose(q).translation.vector;
                [p.x, p.y, p.z]
            }))
            .collect();
        let weights: Vec<f64> = match tracker.filter(|t| t.mpe_um.is_some()) {
            Some(t) => positions
                .iter()
                .map(|&p| t.sigma_mm(p).map_or(1.0, |s| 1.0 / (s * s)))
                .collect(),
            None => Vec::new(),
        };
        if !weights.is_empty() {
            for (b, w) in blocks
                .iter_mut()
                .chain(extra_blocks.iter_mut())
                .chain(prior_blocks.iter_mut())
                .zip(&weights)
            {
                b.scale_mut(w.sqrt());
            }
            ridge *= mean(&weights[..pool.len()]);
        }
        let display: Vec<f64> = parameters
            .iter()
            .zip(&scales)
            .map(|(&p, &s)| {
                if s > 0.0 {
                    per_display_unit(p) / s
                } else {
                    0.0
                }
            })
            .collect();
        let lengths = parameters.iter().filter(|p| p.is_length()).count().max(1) as f64;
        let angles = parameters.iter().filter(|p| !p.is_length()).count().max(1) as f64;
        let parameter_weight = DMatrix::from_fn(k, k, |r, c| {
            if r != c || display[c] == 0.0 {
                0.0
            } else {
                let group = if parameters[c].is_length() {
                    lengths
                } else {
                    angles
                };
                1.0 / (display[c] * display[c] * group)
            }
        });
        let prior_refs: Vec<&DMatrix<f64>> = prior_blocks.iter().collect();
        let base = information(&prior_refs, k, ridge);
        Ok(Prepared {
            parameters,
            pool: blocks,
            extra: extra_blocks,
            prior: prior_blocks,
            display,
            ridge,
            workspace,
            parameter_weight,
            base,
            weights,
        })
    }

    /// Whether the variances are in mm² (weighed by the tracker's uncertainty) rather than
    /// per σ².
    pub fn weighted(&self) -> bool {
        !self.weights.is_empty()
    }

    /// `L` of a linear criterion: `W`, `L_A`, or their sum each divided by its value for
    /// information `W` (a design spread like the pool).
    fn weight(&self, criterion: Criterion) -> DMatrix<f64> {
        match criterion {
            Criterion::D | Criterion::I => self.workspace.clone(),
            Criterion::A => self.parameter_weight.clone(),
            Criterion::Ia => {
                let k = self.workspace.nrows();
                let spread = (&self.workspace + DMatrix::identity(k, k) * self.ridge)
                    .try_inverse()
                    .unwrap_or_else(|| DMatrix::identity(k, k));
                let i = (&self.workspace * &spread).trace();
                let a = (&self.parameter_weight * &spread).trace();
                if i > 0.0 && a > 0.0 && i.is_finite() && a.is_finite() {
                    &self.workspace / i + &self.parameter_weight / a
                } else {
                    self.workspace.clone()
                }
            }
        }
    }

    /// What a set of poses achieves (with the measured poses): [`SetFigures`], for the
    /// candidates `pool` (indices) and the first `extra` further poses.
    pub fn figures(&self, pool: &[usize], extra: usize) -> SetFigures {
        let blocks: Vec<&DMatrix<f64>> = pool
            .iter()
            .map(|&i| &self.pool[i])
            .chain(self.extra.iter().take(extra))
            .collect();
        // The weights of those blocks, to undo for the observability indices, which are of
        // the Jacobian as such.
        let unweigh: Vec<f64> = if self.weighted() {
            let (n, e) = (self.pool.len(), self.extra.len());
            self.weights[n + e..]
                .iter()
                .chain(pool.iter().map(|&i| &self.weights[i]))
                .chain(self.weights[n..n + extra.min(e)].iter())
                .map(|w| 1.0 / w.sqrt())
                .collect()
        } else {
            Vec::new()
        };
        let blocks = &blocks[..];
        let m = with_blocks(self.base.clone(), blocks);
        let (mean_variance, parameter_variance) = match m.try_inverse() {
            Some(m_inv) => (
                (&self.workspace * &m_inv).trace(),
                (&self.parameter_weight * &m_inv).trace(),
            ),
            None => (f64::INFINITY, f64::INFINITY),
        };
        let rows: Vec<&DMatrix<f64>> = self.prior.iter().chain(blocks.iter().copied()).collect();
        let k = self.parameters.len();
        let mut j = DMatrix::zeros(3 * rows.len(), k);
        for (i, b) in rows.iter().enumerate() {
            j.rows_mut(3 * i, 3).copy_from(b);
            if let Some(u) = unweigh.get(i) {
                j.rows_mut(3 * i, 3).scale_mut(*u);
            }
        }
        for (c, f) in self.display.iter().enumerate() {
            j.column_mut(c).scale_mut(*f);
        }
        SetFigures {
            poses: rows.len(),
            mean_variance,
            parameter_variance,
            observability: observability(&j, rows.len()),
        }
    }
}

/// The selection (module docs), and what it achieves. `advance` is told of each pose
/// chosen.
///
/// # Errors
///
/// [`PlanError::Jacobian`] when the identification's Jacobian cannot be formed.
pub fn select(
    robot: &Robot,
    options: &PlanOptions,
    candidates: &[PlannedPose],
    advance: &(dyn Fn(u64) + Sync),
) -> Result<Selection, PlanError> {
    let prior = options.prior.as_ref();
    let prepared = Prepared::new(
        robot,
        candidates,
        &[],
        prior.map_or(&[][..], |p| &p.joints[..]),
        options.rank_tolerance,
        options.tracker.as_ref(),
    )?;
    let mut field = match prior.and_then(|p| p.field.as_ref()) {
        Some(f) => {
            let at: Vec<[f64; 3]> = candidates.iter().map(|c| c.position_mm).collect();
            Some(FieldVariance::new(f, &at)?)
        }
        None => None,
    };
    Ok(select_prepared(
        options,
        candidates,
        &prepared,
        field.as_mut(),
        advance,
    ))
}

/// [`select`] on Jacobians computed already; `field` is conditioned on the poses chosen.
pub fn select_prepared(
    options: &PlanOptions,
    candidates: &[PlannedPose],
    prepared: &Prepared,
    mut field: Option<&mut FieldVariance>,
    advance: &(dyn Fn(u64) + Sync),
) -> Selection {
    let blocks = &prepared.pool;
    let k = prepared.parameters.len();
    let weight = prepared.weight(options.criterion);
    let mut stacked = DMatrix::zeros(3 * blocks.len(), k);
    for (i, b) in blocks.iter().enumerate() {
        stacked.rows_mut(3 * i, 3).copy_from(b);
    }
    let start = prepared
        .base
        .clone()
        .try_inverse()
        .unwrap_or_else(|| DMatrix::identity(k, k) / prepared.ridge);
    let mut design = Design::new(options.criterion, &weight, &stacked, start);
    // Coverage counts from the positions measured already.
    let measured: &[[f64; 3]] = options.prior.as_ref().map_or(&[], |p| &p.positions_mm[..]);
    let mut nearest: Vec<f64> = candidates
        .par_iter()
        .map(|c| {
            measured
                .iter()
                .map(|&m| distance(c.position_mm, m))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let mut taken = vec![false; candidates.len()];
    let mut chosen = Vec::with_capacity(options.count);
    let w = options.coverage_weight;
    for _ in 0..options.count {
        let gains = design.gains();
        // With a table, the field's reducible variance stands for the coverage.
        let cover: Vec<f64> = match field.as_deref() {
            Some(f) => f.reducible_mm2(),
            None => nearest.clone(),
        };
        let open = || (0..candidates.len()).filter(|&i| !taken[i]);
        let max_gain = open().map(|i| gains[i]).fold(0.0, f64::max);
        let max_cover = open()
            .map(|i| cover[i])
            .filter(|d| d.is_finite())
            .fold(0.0, f64::max);
        let score = |i: usize| {
            let g = if max_gain > 0.0 {
                gains[i] / max_gain
            } else {
                0.0
            };
            let c = if max_cover > 0.0 && cover[i].is_finite() {
                cover[i] / max_cover
            } else {
                1.0
            };
            (1.0 - w) * g + w * c
        };
        let best = best_of(open(), score).expect("the pool holds at least count candidates");
        taken[best] = true;
        chosen.push(best);
        design.update(&blocks[best], 1.0);
        if let Some(f) = field.as_deref_mut() {
            f.take(best);
        }
        let p = candidates[best].position_mm;
        nearest
            .par_iter_mut()
            .zip(candidates.par_iter())
            .for_each(|(d, c)| *d = d.min(distance(c.position_mm, p)));
        advance(1);
    }
    exchange(
        options,
        blocks,
        &mut design,
        &mut chosen,
        &mut taken,
        &prepared.base,
    );
    let picked: Vec<&DMatrix<f64>> = chosen.iter().map(|&i| &blocks[i]).collect();
    let m = with_blocks(prepared.base.clone(), &picked);
    let m_inv = m.clone().try_inverse();
    let trace = |l: &DMatrix<f64>| {
        m_inv
            .as_ref()
            .map_or(f64::INFINITY, |m_inv| (l * m_inv).trace())
    };
    let mean_variance = trace(&prepared.workspace);
    let bound = |l: &DMatrix<f64>| {
        variance_bound(&stacked, l, options.count, &prepared.base).max(capped_bound(
            &stacked,
            l,
            &prepared.base,
            &chosen,
        ))
    };
    let i_bound = bound(&prepared.workspace);
    let (criterion_value, criterion_bound) = match options.criterion {
        Criterion::D | Criterion::I => (mean_variance, i_bound),
        other => (trace(&weight), bound(&prepared.weight(other))),
    };
    Selection {
        log_det: log_det(&m),
        mean_variance,
        variance_bound: i_bound,
        criterion_value,
        criterion_bound,
        chosen,
        parameters: prepared.parameters.clone(),
    }
}

/// The index of the largest score, the earlier one on ties.
fn best_of(indices: impl Iterator<Item = usize>, score: impl Fn(usize) -> f64) -> Option<usize> {
    indices
        .fold(None, |best: Option<(usize, f64)>, i| {
            let s = score(i);
            match best {
                Some((_, b)) if b >= s => best,
                _ => Some((i, s)),
            }
        })
        .map(|(i, _)| i)
}

/// Exchange passes after the greedy choice (Fedorov's exchange, one pose at a time): each
/// chosen pose in turn is taken out, and the candidate (itself included) that the
/// criterion gains most from put in its place; a pass that changes nothing ends them.
/// The coverage term is not weighed here: it shapes the greedy start, and an exchange
/// only ever improves the criterion.
fn exchange(
    options: &PlanOptions,
    blocks: &[DMatrix<f64>],
    design: &mut Design<'_>,
    chosen: &mut [usize],
    taken: &mut [bool],
    base: &DMatrix<f64>,
) {
    for _ in 0..options.exchange_passes {
        let mut changed = false;
        for slot in chosen.iter_mut() {
            let out = *slot;
            if !design.update(&blocks[out], -1.0) {
                continue;
            }
            let gains = design.gains();
            let best = best_of((0..blocks.len()).filter(|&i| i == out || !taken[i]), |i| {
                gains[i]
            })
            .unwrap_or(out);
            // Only a clear gain swaps, so that rounding cannot cycle two candidates.
            let swap = best != out && gains[best] > gains[out] * (1.0 + 1e-9) + 1e-12;
            let put = if swap { best } else { out };
            design.update(&blocks[put], 1.0);
            if swap {
                taken[out] = false;
                taken[put] = true;
                *slot = put;
                changed = true;
            }
        }
        // A fresh inverse after each pass: the rank-3 updates accumulate rounding.
        let picked: Vec<&DMatrix<f64>> = chosen.iter().map(|&i| &blocks[i]).collect();
        if let Some(m_inv) = with_blocks(base.clone(), &picked).try_inverse() {
            design.m_inv = m_inv;
            design.refresh();
        }
        if !changed {
            break;
        }
    }
}

/// The largest joint travel between two joint vectors: revolute joints in rad, prismatic
/// ones in metres.
fn travel(robot: &Robot, a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .enumerate()
        .map(|(i, (x, y))| match robot.joint_kind(i) {
            JointKind::Revolute => (x - y).abs(),
            JointKind::Prismatic => (x - y).abs() / 1000.0,
        })
        .fold(0.0, f64::max)
}

/// An open path through `poses`: nearest neighbour from the pose nearest the home
/// posture, then 2-opt until no reversal shortens it (at most 100 passes).
pub fn order(robot: &Robot, poses: &[PlannedPose]) -> (Vec<usize>, f64) {
    let n = poses.len();
    if n == 0 {
        return (Vec::new(), 0.0);
    }
    let d = |i: usize, j: usize| travel(robot, &poses[i].joints, &poses[j].joints);
    let home = robot.home();
    let start = (0..n)
        .min_by(|&a, &b| {
            travel(robot, &poses[a].joints, home).total_cmp(&travel(robot, &poses[b].joints, home))
        })
        .expect("not empty");
    let mut path = vec![start];
    let mut visited = vec![false; n];
    visited[start] = true;
    for _ in 1..n {
        let last = *path.last().expect("not empty");
        let next = (0..n)
            .filter(|&j| !visited[j])
            .min_by(|&a, &b| d(last, a).total_cmp(&d(last, b)))
            .expect("unvisited remain");
        visited[next] = true;
        path.push(next);
    }
    for _ in 0..100 {
        let mut improved = false;
        for i in 0..n.saturating_sub(2) {
            for j in i + 2..n {
                // Reversing path[i+1..=j]: edges (i, i+1) and (j, j+1) become (i, j) and
                // (i+1, j+1); an open path's end has no edge after it.
                let (a, b, c) = (path[i], path[i + 1], path[j]);
                let after = path.get(j + 1).copied();
                let before = d(a, b) + after.map_or(0.0, |e| d(c, e));
                let reversed = d(a, c) + after.map_or(0.0, |e| d(b, e));
                if reversed < before - 1e-12 {
                    path[i + 1..=j].reverse();
                    improved = true;
                }
            }
        }
        if !improved {
            break;
        }
    }
    let length = path.windows(2).map(|w| d(w[0], w[1])).sum();
    (path, length)
}

/// Plans the poses: candidates, selection, order. `stage` names each stage with its
/// units; `advance` counts them.
///
/// # Errors
///
/// As [`check`], [`candidates`] and [`select`].
pub fn plan(
    robot: &Robot,
    options: &PlanOptions,
    stage: &(dyn Fn(&str, u64) + Sync),
    advance: &(dyn Fn(u64) + Sync),
) -> Result<Plan, PlanError> {
    check(robot, options)?;
    stage("drawing candidates", options.pool as u64);
    let (pool, draws) = candidates(robot, options, advance)?;
    // The random comparison: twice the count drawn from the same workspace in another
    // stream of the seed, apart from the pool; the workspace's branch only.
    let random_count = (2 * options.count).min(MAX_POOL);
    stage("drawing random poses to compare", random_count as u64);
    let random = candidates_from(
        robot,
        &PlanOptions {
            pool: random_count,
            count: random_count,
            branches: Branches::Home,
            ..options.clone()
        },
        RANDOM_STREAM,
        advance,
    )
    .map(|(found, _)| found)
    .unwrap_or_default();
    stage("selecting", options.count as u64);
    let prior = options.prior.as_ref();
    let prepared = Prepared::new(
        robot,
        &pool,
        &random,
        prior.map_or(&[][..], |p| &p.joints[..]),
        options.rank_tolerance,
        options.tracker.as_ref(),
    )?;
    let positions =
        |poses: &[PlannedPose]| -> Vec<[f64; 3]> { poses.iter().map(|c| c.position_mm).collect() };
    // The field over the pool and the first random set: the selection weighs the pool's
    // candidates; the random set is conditioned on apart, for the comparison.
    let random_n = options.count.min(random.len());
    let field_prior = prior.and_then(|p| p.field.as_ref());
    let mut field = match field_prior {
        Some(f) => {
            let mut at = positions(&pool);
            at.extend(positions(&random[..random_n]));
            Some(FieldVariance::new(f, &at)?)
        }
        None => None,
    };
    let before = field.clone();
    let Selection {
        chosen,
        parameters,
        log_det,
        mean_variance,
        variance_bound,
        criterion_value,
        criterion_bound,
    } = select_prepared(options, &pool, &prepared, field.as_mut(), advance);
    let field_variance_mm2 = before.map(|before| {
        let over_pool = |f: &FieldVariance| mean(&f.variance_mm2()[..pool.len()]);
        let conditioned = |indices: &mut dyn Iterator<Item = usize>| {
            let mut f = before.clone();
            indices.for_each(|i| f.take(i));
            over_pool(&f)
        };
        [
            over_pool(&before),
            conditioned(&mut chosen.iter().copied()),
            conditioned(&mut (pool.len()..pool.len() + random_n)),
        ]
    });
    let planned_figures = prepared.figures(&chosen, 0);
    let random_figures: Vec<SetFigures> = if random.len() == random_count {
        [options.count, random_count]
            .iter()
            .map(|&n| prepared.figures(&[], n))
            .collect()
    } else {
        Vec::new()
    };
    let tracker_sigma_mm = prepared.weighted().then(|| {
        let sigma = prepared.weights[..pool.len()]
            .iter()
            .map(|w| 1.0 / w.sqrt());
        [
            sigma.clone().fold(f64::INFINITY, f64::min),
            sigma.fold(0.0, f64::max),
        ]
    });
    let other_branches = chosen.iter().filter(|&&i| !pool[i].workspace).count();
    let workspace_candidates = pool.iter().filter(|c| c.workspace).count();
    let picked: Vec<PlannedPose> = chosen.iter().map(|&i| pool[i].clone()).collect();
    let (path, path_travel) = order(robot, &picked);
    let poses: Vec<PlannedPose> = path.iter().map(|&i| picked[i].clone()).collect();
    let min_distance_mm = poses
        .iter()
        .enumerate()
        .flat_map(|(i, a)| {
            poses[i + 1..]
                .iter()
                .map(|b| distance(a.position_mm, b.position_mm))
        })
        .reduce(f64::min);
    Ok(Plan {
        poses,
        parameters,
        pool: pool.len(),
        draws,
        log_det,
        mean_variance,
        variance_bound,
        min_distance_mm,
        path_travel,
        criterion_value,
        criterion_bound,
        planned: planned_figures,
        random: random_figures,
        field_variance_mm2,
        tracker_sigma_mm,
        workspace_candidates,
        other_branches,
    })
}

fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len().max(1) as f64
}

/// The seed's stream of the random poses a plan is compared with (the pool's is 0).
const RANDOM_STREAM: u64 = 1;

/// The configuration label of a joint vector, for robots with a closed form.
pub type ConfigLabel<'a> = dyn Fn(&[f64]) -> u8 + 'a;

/// The plan as CSV: `#` comment lines, then `j1..jn` (degrees; mm for prismatic joints),
/// the nominal `x,y,z` (mm) and `a,b,c` (KUKA degrees) at those joints, and `config` when
/// `config` labels them. `tablec simulate --poses` measures it; a measurement adds
/// `mx,my,mz` for `build` and `calibrate`.
pub fn write_csv(
    robot: &Robot,
    plan: &Plan,
    comments: &[String],
    config: Option<&ConfigLabel<'_>>,
) -> String {
    let mut out = String::new();
    for c in comments {
        for line in c.lines() {
            let _ = writeln!(out, "# {line}");
        }
    }
    let n = robot.joint_count();
    let mut header: Vec<String> = (1..=n).map(|j| format!("j{j}")).collect();
    header.extend(["x", "y", "z", "a", "b", "c"].map(String::from));
    if config.is_some() {
        header.push("config".into());
    }
    let _ = writeln!(out, "{}", header.join(","));
    let fixed = |v: f64| {
        let text = format!("{v:.DECIMALS$}");
        // A rounded negative zero is written as zero.
        if text
            .trim_start_matches('-')
            .chars()
            .all(|c| c == '0' || c == '.')
        {
            text.trim_start_matches('-').to_string()
        } else {
            text
        }
    };
    for pose in &plan.poses {
        let mut fields: Vec<String> = pose
            .joints
            .iter()
            .enumerate()
            .map(|(i, &v)| match robot.joint_kind(i) {
                JointKind::Revolute => fixed(v.to_degrees()),
                JointKind::Prismatic => fixed(v),
            })
            .collect();
        fields.extend(pose.position_mm.iter().map(|&v| fixed(v)));
        fields.extend(pose.abc_deg.iter().map(|&v| fixed(v)));
        if let Some(label) = config {
            fields.push(label(&pose.joints).to_string());
        }
        let _ = writeln!(out, "{}", fields.join(","));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use adwi_identify::calibrate::design_jacobians;

    fn ur5() -> Robot {
        Robot::load(adwi_robot::model::shipped_robot_path("ur5")).unwrap()
    }

    fn options(count: usize, pool: usize) -> PlanOptions {
        PlanOptions {
            boxes_mm: vec![([-600.0, -600.0, 0.0], [600.0, 600.0, 700.0])],
            count,
            pool,
            seed: 7,
            tracker: Some(TrackerSight {
                position_mm: [2000.0, 0.0, 500.0],
                range_mm: [500.0, 3000.0],
                sight_cone_deg: Some(70.0),
                mpe_um: None,
            }),
            orientations: None,
            coverage_weight: 0.3,
            rank_tolerance: 1e-6,
            criterion: Criterion::I,
            exchange_passes: 2,
            prior: None,
            branches: Branches::Home,
        }
    }

    fn make(o: &PlanOptions) -> String {
        let robot = ur5();
        let p = plan(&robot, o, &|_, _| {}, &|_| {}).unwrap();
        write_csv(&robot, &p, &[], None)
    }

    #[test]
    fn the_same_seed_gives_the_same_bytes_and_another_seed_other_poses() {
        let o = options(20, 200);
        let a = make(&o);
        assert_eq!(a, make(&o));
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        assert_eq!(a, one.install(|| make(&o)));
        assert_ne!(a, make(&PlanOptions { seed: 8, ..o }));
    }

    #[test]
    fn every_planned_pose_is_within_the_limits_the_box_and_the_cone() {
        let robot = ur5();
        let o = options(30, 300);
        let p = plan(&robot, &o, &|_, _| {}, &|_| {}).unwrap();
        assert_eq!(p.poses.len(), 30);
        let tracker = o.tracker.as_ref().unwrap();
        for pose in &p.poses {
            assert!(robot.within_limits(&pose.joints));
            // Recomputed from the joints, not taken from the candidate.
            let tcp = robot.tcp_pose(&pose.joints);
            let t = tcp.translation.vector;
            let (min, max) = o.boxes_mm[0];
            assert!((0..3).all(|a| min[a] <= t[a] && t[a] <= max[a]), "{t:?}");
            let to_tracker = Vector3::from(tracker.position_mm) - t;
            let range = to_tracker.norm();
            assert!((500.0..=3000.0).contains(&range));
            let axis = tcp.rotation * Vector3::z();
            assert!(axis.angle(&to_tracker).to_degrees() <= 70.0);
        }
        // Every pose once.
        let mut seen: Vec<String> = p.poses.iter().map(|q| format!("{:?}", q.joints)).collect();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), 30);
    }

    /// With allowed orientations the candidates come from inverse kinematics: every pose
    /// within the tolerance of one of them, and in the box.
    #[test]
    fn planned_poses_keep_an_allowed_orientation() {
        let robot = Robot::load(adwi_robot::model::shipped_robot_path("kr150-2")).unwrap();
        let allowed = [[0.0, 90.0, 0.0], [0.0, 45.0, 0.0]];
        let o = PlanOptions {
            boxes_mm: vec![([1350.0, 50.0, 850.0], [2150.0, 850.0, 1650.0])],
            tracker: None,
            orientations: Some(AllowedOrientations {
                abc_deg: allowed.to_vec(),
                tolerance_deg: 5.0,
            }),
            ..options(20, 100)
        };
        let p = plan(&robot, &o, &|_, _| {}, &|_| {}).unwrap();
        // A bound on every choice holds for this one.
        assert!(
            p.variance_bound > 0.0 && p.variance_bound <= p.mean_variance,
            "{} vs {}",
            p.variance_bound,
            p.mean_variance
        );
        for pose in &p.poses {
            let tcp = robot.tcp_pose(&pose.joints);
            let rotation = tcp.rotation.to_rotation_matrix();
            let off = allowed
                .iter()
                .map(|abc| {
                    rotation_from_kuka_abc_deg(*abc)
                        .angle_to(&rotation)
                        .to_degrees()
                })
                .fold(f64::INFINITY, f64::min);
            assert!(off <= 5.0, "{off}°");
            let t = tcp.translation.vector;
            assert!((1350.0..=2150.0).contains(&t.x) && (850.0..=1650.0).contains(&t.z));
        }
    }

    /// A single pose has no smallest distance to report, and is planned.
    #[test]
    fn one_pose_is_planned_without_a_smallest_distance() {
        let robot = ur5();
        let p = plan(&robot, &options(1, 20), &|_, _| {}, &|_| {}).unwrap();
        assert_eq!(p.poses.len(), 1);
        assert_eq!(p.min_distance_mm, None);
        let two = plan(&robot, &options(2, 20), &|_, _| {}, &|_| {}).unwrap();
        let d = distance(two.poses[0].position_mm, two.poses[1].position_mm);
        assert_eq!(two.min_distance_mm, Some(d));
    }

    /// A seven-axis arm has no closed form: its candidates are solved from the posture
    /// table, and the plan keeps every constraint and is the same at any thread count.
    #[test]
    fn a_seven_axis_arm_plans_at_allowed_orientations_the_same_at_any_thread_count() {
        let robot = Robot::load(adwi_robot::model::shipped_file("iiwa14", "robot.toml")).unwrap();
        let o = PlanOptions {
            boxes_mm: vec![([400.0, -200.0, 300.0], [600.0, 200.0, 600.0])],
            tracker: None,
            orientations: Some(AllowedOrientations {
                abc_deg: vec![[0.0, 180.0, 0.0]],
                tolerance_deg: 5.0,
            }),
            ..options(20, 200)
        };
        let p = plan(&robot, &o, &|_, _| {}, &|_| {}).unwrap();
        let down = rotation_from_kuka_abc_deg([0.0, 180.0, 0.0]);
        for pose in &p.poses {
            assert!(robot.within_limits(&pose.joints));
            let tcp = robot.tcp_pose(&pose.joints);
            assert!(
                down.angle_to(&tcp.rotation.to_rotation_matrix())
                    .to_degrees()
                    <= 5.0
            );
            let t = tcp.translation.vector;
            let (min, max) = o.boxes_mm[0];
            assert!((0..3).all(|a| min[a] <= t[a] && t[a] <= max[a]), "{t:?}");
        }
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let written = write_csv(&robot, &p, &[], None);
        let alone = one.install(|| plan(&robot, &o, &|_, _| {}, &|_| {}).unwrap());
        assert_eq!(written, write_csv(&robot, &alone, &[], None));
    }

    /// The greedy choice is D-better than the same number of the pool's first
    /// candidates (a random draw), on the same pool and criterion.
    #[test]
    fn the_selection_beats_a_random_choice_on_its_criterion() {
        let robot = ur5();
        let o = PlanOptions {
            coverage_weight: 0.0,
            criterion: Criterion::D,
            ..options(25, 300)
        };
        let (pool, _) = candidates(&robot, &o, &|_| {}).unwrap();
        let selection = select(&robot, &o, &pool, &|_| {}).unwrap();
        let (parameters, chosen) = (selection.parameters, selection.log_det);
        let joints: Vec<Vec<f64>> = pool.iter().map(|c| c.joints.clone()).collect();
        let (_, blocks) = design_jacobians(&robot, &joints, o.rank_tolerance).unwrap();
        let first: Vec<&DMatrix<f64>> = blocks.iter().take(25).collect();
        let random = log_det(&information(
            &first,
            parameters.len(),
            1e-3 / pool.len() as f64,
        ));
        assert!(chosen > random, "{chosen} vs {random}");
    }

    /// The Woodbury gain equals the difference of log-determinants computed outright.
    #[test]
    fn the_rank_three_gain_is_the_log_det_difference() {
        let robot = ur5();
        let o = options(5, 50);
        let (pool, _) = candidates(&robot, &o, &|_| {}).unwrap();
        let joints: Vec<Vec<f64>> = pool.iter().map(|c| c.joints.clone()).collect();
        let (parameters, blocks) = design_jacobians(&robot, &joints, 1e-6).unwrap();
        let k = parameters.len();
        let some: Vec<&DMatrix<f64>> = blocks.iter().take(10).collect();
        let m = information(&some, k, 1e-3);
        let m_inv = m.clone().try_inverse().unwrap();
        let b = &blocks[20];
        let mut with = some.clone();
        with.push(b);
        let direct = log_det(&information(&with, k, 1e-3)) - log_det(&m);
        assert!((gain(b, &m_inv) - direct).abs() < 1e-6 * direct.abs().max(1.0));
    }

    /// The stacked, chunked gains equal the per-block formulas, and the I-optimality gain
    /// is the drop of `tr(W M⁻¹)` computed outright.
    #[test]
    fn the_stacked_gains_are_the_per_block_gains() {
        let robot = ur5();
        let o = options(5, 600);
        let (pool, _) = candidates(&robot, &o, &|_| {}).unwrap();
        let joints: Vec<Vec<f64>> = pool.iter().map(|c| c.joints.clone()).collect();
        let (parameters, blocks) = design_jacobians(&robot, &joints, 1e-6).unwrap();
        let k = parameters.len();
        let all: Vec<&DMatrix<f64>> = blocks.iter().collect();
        let workspace = information(&all, k, 0.0) / blocks.len() as f64;
        let mut stacked = DMatrix::zeros(3 * blocks.len(), k);
        for (i, b) in blocks.iter().enumerate() {
            stacked.rows_mut(3 * i, 3).copy_from(b);
        }
        let some: Vec<&DMatrix<f64>> = blocks.iter().step_by(7).take(40).collect();
        let m = information(&some, k, 1e-3);
        let m_inv = m.clone().try_inverse().unwrap();
        for criterion in [Criterion::D, Criterion::I, Criterion::A, Criterion::Ia] {
            let design = Design::new(criterion, &workspace, &stacked, m_inv.clone());
            let gains = design.gains();
            assert_eq!(gains.len(), blocks.len());
            for (b, fast) in blocks.iter().zip(&gains) {
                let slow = match criterion {
                    Criterion::D => gain(b, &m_inv),
                    _ => variance_gain(b, &m_inv, &design.g),
                };
                assert!(
                    (fast - slow).abs() <= 1e-9 * slow.abs().max(1e-12),
                    "{fast} vs {slow}"
                );
            }
        }
        let b = &blocks[3];
        let mut with = some.clone();
        with.push(b);
        let after = information(&with, k, 1e-3).try_inverse().unwrap();
        let direct = (&workspace * &m_inv).trace() - (&workspace * after).trace();
        let g = &m_inv * &workspace * &m_inv;
        let woodbury = variance_gain(b, &m_inv, &g);
        assert!(
            (woodbury - direct).abs() < 1e-8 * direct.abs(),
            "{woodbury} vs {direct}"
        );
    }

    /// Exchange passes never make the criterion worse than the greedy choice: the mean
    /// prediction variance over the pool, and the log det, on the same pool.
    #[test]
    fn exchange_improves_on_the_greedy_choice() {
        let robot = ur5();
        let (pool, _) = candidates(&robot, &options(25, 400), &|_| {}).unwrap();
        let joints: Vec<Vec<f64>> = pool.iter().map(|c| c.joints.clone()).collect();
        let (_, blocks) = design_jacobians(&robot, &joints, 1e-6).unwrap();
        let k = blocks[0].ncols();
        let ridge = 1e-3 / pool.len() as f64;
        let all: Vec<&DMatrix<f64>> = blocks.iter().collect();
        let workspace = information(&all, k, 0.0) / pool.len() as f64;
        let variance = |chosen: &[usize]| {
            let picked: Vec<&DMatrix<f64>> = chosen.iter().map(|&i| &blocks[i]).collect();
            (&workspace * information(&picked, k, ridge).try_inverse().unwrap()).trace()
        };
        for criterion in [Criterion::I, Criterion::D] {
            let o = |passes| PlanOptions {
                criterion,
                coverage_weight: 0.0,
                exchange_passes: passes,
                ..options(25, 400)
            };
            let greedy = select(&robot, &o(0), &pool, &|_| {}).unwrap();
            let exchanged = select(&robot, &o(3), &pool, &|_| {}).unwrap();
            // The bound holds for either, and the figure reported is the variance.
            for s in [&greedy, &exchanged] {
                assert!(s.variance_bound > 0.0 && s.variance_bound <= s.mean_variance);
                assert!((s.mean_variance - variance(&s.chosen)).abs() < 1e-9 * s.mean_variance);
            }
            let (greedy_det, det) = (greedy.log_det, exchanged.log_det);
            let (greedy, exchanged) = (greedy.chosen, exchanged.chosen);
            match criterion {
                Criterion::I => {
                    let (a, b) = (variance(&exchanged), variance(&greedy));
                    assert!(a <= b * (1.0 + 1e-9), "{a} vs {b}");
                }
                Criterion::D => assert!(det >= greedy_det - 1e-9, "{det} vs {greedy_det}"),
                _ => unreachable!("only I and D are exchanged here"),
            }
            let mut distinct = exchanged.clone();
            distinct.sort_unstable();
            distinct.dedup();
            assert_eq!(distinct.len(), 25);
        }
    }

    #[test]
    fn two_opt_never_lengthens_the_nearest_neighbour_path() {
        let robot = ur5();
        let o = options(40, 200);
        let (pool, _) = candidates(&robot, &o, &|_| {}).unwrap();
        let (path, length) = order(&robot, &pool[..40]);
        let mut sorted = path.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..40).collect::<Vec<_>>());
        let in_order: f64 = (0..39)
            .map(|i| travel(&robot, &pool[i].joints, &pool[i + 1].joints))
            .sum();
        assert!(length <= in_order, "{length} vs {in_order}");
    }

    #[test]
    fn requests_are_sized_and_refused_with_their_figure() {
        let robot = ur5();
        let e = check(&robot, &options(MAX_POSES + 1, MAX_POOL)).unwrap_err();
        assert!(e.to_string().contains("5001 poses"), "{e}");
        let e = check(&robot, &options(5000, 50_000)).unwrap_err();
        assert!(e.to_string().contains("multiply-adds"), "{e}");
        let mut o = options(10, 20);
        o.boxes_mm = vec![([5000.0; 3], [5001.0; 3])];
        let e = plan(&robot, &o, &|_, _| {}, &|_| {}).unwrap_err();
        assert!(
            matches!(e, PlanError::TooFewCandidates { found: 0, .. }),
            "{e}"
        );
    }

    /// The random poses compared with are drawn from the same workspace apart from the
    /// pool (none of them a candidate), as many as planned and twice as many, and their
    /// figures are those of their own information over the pool's workspace.
    #[test]
    fn the_random_comparison_is_drawn_apart_from_the_pool() {
        let robot = ur5();
        let o = options(15, 150);
        let p = plan(&robot, &o, &|_, _| {}, &|_| {}).unwrap();
        assert_eq!(
            p.random.iter().map(|f| f.poses).collect::<Vec<_>>(),
            [15, 30]
        );
        let (pool, _) = candidates(&robot, &o, &|_| {}).unwrap();
        let random = candidates_from(
            &robot,
            &PlanOptions {
                pool: 30,
                count: 30,
                ..o.clone()
            },
            RANDOM_STREAM,
            &|_| {},
        )
        .unwrap()
        .0;
        assert!(random
            .iter()
            .all(|r| pool.iter().all(|c| c.joints != r.joints)));
        // Recomputed outright: the mean prediction variance of the first 15 random poses
        // over the pool, with the same parameters and scaling.
        let prepared = Prepared::new(&robot, &pool, &random, &[], o.rank_tolerance, None).unwrap();
        let first: Vec<&DMatrix<f64>> = prepared.extra.iter().take(15).collect();
        let m_inv = with_blocks(prepared.base.clone(), &first)
            .try_inverse()
            .unwrap();
        let direct = (&prepared.workspace * m_inv).trace();
        let reported = p.random[0].mean_variance;
        assert!(
            (direct - reported).abs() < 1e-9 * direct,
            "{direct} vs {reported}"
        );
        // More poses, less variance; and the plan's figures are its own.
        assert!(p.random[1].mean_variance < p.random[0].mean_variance);
        assert!((p.planned.mean_variance - p.mean_variance).abs() < 1e-9 * p.mean_variance);
        assert!(p.planned.observability.is_some());
    }

    /// The A criterion's weight is the parameters' variances in mm and mrad: its trace
    /// against `M⁻¹` is the mean squared error of the lengths plus that of the angles,
    /// computed from the physical Jacobian outright.
    #[test]
    fn the_parameter_variance_is_in_millimetres_and_milliradians() {
        let robot = ur5();
        let o = options(5, 200);
        let (pool, _) = candidates(&robot, &o, &|_| {}).unwrap();
        let prepared = Prepared::new(&robot, &pool, &[], &[], 1e-3, None).unwrap();
        let some: Vec<&DMatrix<f64>> = prepared.pool.iter().take(60).collect();
        let figures = prepared.figures(&(0..60).collect::<Vec<_>>(), 0);
        // The physical Jacobian (mm per mm, mm per mrad).
        let k = prepared.parameters.len();
        let mut j = DMatrix::zeros(3 * some.len(), k);
        for (i, b) in some.iter().enumerate() {
            j.rows_mut(3 * i, 3).copy_from(b);
        }
        for (c, f) in prepared.display.iter().enumerate() {
            j.column_mut(c).scale_mut(*f);
        }
        // The ridge, as the scaled information has it: `ridge · I` there is
        // `ridge · D²` here.
        let ridge = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
            k,
            prepared.display.iter().map(|f| prepared.ridge * f * f),
        ));
        let covariance = (j.transpose() * &j + ridge).try_inverse().unwrap();
        let group = |length: bool| {
            let cols: Vec<usize> = (0..k)
                .filter(|&c| prepared.parameters[c].is_length() == length)
                .collect();
            cols.iter().map(|&c| covariance[(c, c)]).sum::<f64>() / cols.len() as f64
        };
        let direct = group(true) + group(false);
        assert!(
            (figures.parameter_variance - direct).abs() < 1e-4 * direct,
            "{} vs {direct}",
            figures.parameter_variance
        );
    }

    /// A plan that continues from poses measured already adds what they lack: its poses
    /// with them have a lower mean prediction variance than as many random poses with
    /// them, and its bound counts them.
    #[test]
    fn a_plan_continues_from_the_poses_measured_already() {
        let robot = ur5();
        let first = plan(&robot, &options(12, 150), &|_, _| {}, &|_| {}).unwrap();
        let o = PlanOptions {
            seed: 9,
            prior: Some(Prior {
                joints: first.poses.iter().map(|p| p.joints.clone()).collect(),
                positions_mm: first.poses.iter().map(|p| p.position_mm).collect(),
                field: None,
            }),
            ..options(12, 150)
        };
        let second = plan(&robot, &o, &|_, _| {}, &|_| {}).unwrap();
        assert_eq!(second.planned.poses, 24);
        assert_eq!(second.random[0].poses, 24);
        assert!(
            second.planned.mean_variance < second.random[0].mean_variance,
            "{} vs {}",
            second.planned.mean_variance,
            second.random[0].mean_variance
        );
        assert!(second.variance_bound <= second.mean_variance);
        // Without the measured poses the same candidates give a plan of 12 alone.
        let alone = plan(
            &robot,
            &PlanOptions {
                prior: None,
                ..o.clone()
            },
            &|_, _| {},
            &|_| {},
        )
        .unwrap();
        assert!(alone.mean_variance > second.mean_variance);
        let mut bad = o;
        bad.prior.as_mut().unwrap().joints[0].pop();
        let e = check(&robot, &bad).unwrap_err();
        assert!(e.to_string().contains("joint values"), "{e}");
    }

    /// Both bounds hold for every choice: on a pool of 12 candidates, no 9 of them (all
    /// 220 choices tried) have a mean prediction variance below the bound the plan
    /// reports, and the bound is at most the plan's own value.
    #[test]
    fn the_bounds_hold_for_every_choice_of_distinct_poses() {
        let robot = ur5();
        let o = PlanOptions {
            coverage_weight: 0.0,
            ..options(9, 12)
        };
        let (pool, _) = candidates(&robot, &o, &|_| {}).unwrap();
        let prepared = Prepared::new(&robot, &pool, &[], &[], o.rank_tolerance, None).unwrap();
        let s = select_prepared(&o, &pool, &prepared, None, &|_| {});
        let variance = |chosen: &[usize]| {
            let picked: Vec<&DMatrix<f64>> = chosen.iter().map(|&i| &prepared.pool[i]).collect();
            (&prepared.workspace
                * with_blocks(prepared.base.clone(), &picked)
                    .try_inverse()
                    .unwrap())
            .trace()
        };
        // Every choice of 9 of 12 leaves out 3.
        let mut best = f64::INFINITY;
        for a in 0..12 {
            for b in a + 1..12 {
                for c in b + 1..12 {
                    let chosen: Vec<usize> =
                        (0..12).filter(|&i| i != a && i != b && i != c).collect();
                    best = best.min(variance(&chosen));
                }
            }
        }
        assert!(
            s.variance_bound <= best * (1.0 + 1e-9),
            "{} vs {best}",
            s.variance_bound
        );
        assert!(s.mean_variance >= best * (1.0 - 1e-9));
        assert!(s.variance_bound <= s.mean_variance);
        let k = prepared.parameters.len();
        let mut stacked = DMatrix::zeros(36, k);
        for (i, b) in prepared.pool.iter().enumerate() {
            stacked.rows_mut(3 * i, 3).copy_from(b);
        }
        let capped = capped_bound(&stacked, &prepared.workspace, &prepared.base, &s.chosen);
        assert!(
            capped >= 0.0 && capped <= best * (1.0 + 1e-9),
            "{capped} vs {best}"
        );
    }

    fn kr150(count: usize, pool: usize, branches: Branches) -> (Robot, PlanOptions) {
        let robot = Robot::load(adwi_robot::model::shipped_robot_path("kr150-2")).unwrap();
        let o = PlanOptions {
            boxes_mm: vec![([1350.0, 50.0, 850.0], [2150.0, 850.0, 1650.0])],
            tracker: None,
            orientations: Some(AllowedOrientations {
                abc_deg: vec![[0.0, 90.0, 0.0]],
                tolerance_deg: 5.0,
            }),
            coverage_weight: 0.0,
            branches,
            seed: 1,
            ..options(count, pool)
        };
        (robot, o)
    }

    /// With every branch, the pool holds the home branch's candidates of the same draws
    /// and the other branches' (wrist flips, at this orientation): a plan from it predicts
    /// the home branch's positions better than any choice from the home branch alone can
    /// (the narrow pool's bound), over the same workspace.
    #[test]
    fn a_plan_from_every_branch_beats_the_home_branchs_bound() {
        let (robot, wide) = kr150(30, 900, Branches::All);
        let w = plan(&robot, &wide, &|_, _| {}, &|_| {}).unwrap();
        assert!(
            w.workspace_candidates < w.pool && w.other_branches > 0,
            "{w:?}"
        );
        // The narrow pool: the same draws' home solutions, the same candidates in order.
        let (_, narrow) = kr150(30, w.workspace_candidates, Branches::Home);
        let n = plan(&robot, &narrow, &|_, _| {}, &|_| {}).unwrap();
        let (wide_pool, _) = candidates(&robot, &wide, &|_| {}).unwrap();
        let (narrow_pool, _) = candidates(&robot, &narrow, &|_| {}).unwrap();
        let home: Vec<&PlannedPose> = wide_pool.iter().filter(|c| c.workspace).collect();
        assert_eq!(home.len(), narrow_pool.len());
        assert!(home
            .iter()
            .zip(&narrow_pool)
            .all(|(a, b)| a.joints == b.joints));
        assert!(
            w.mean_variance < n.variance_bound,
            "every branch {} against the home branch's bound {} (its plan {})",
            w.mean_variance,
            n.variance_bound,
            n.mean_variance
        );
        // Every pose keeps the constraints, whichever its branch.
        for pose in &w.poses {
            assert!(robot.within_limits(&pose.joints));
            let t = robot.tcp_pose(&pose.joints).translation.vector;
            assert!((1350.0..=2150.0).contains(&t.x) && (850.0..=1650.0).contains(&t.z));
        }
    }

    /// A redundant arm's other branch is another posture of the same pose: another elbow
    /// angle, within the limits, at the allowed orientation.
    #[test]
    fn a_seven_axis_arms_other_branch_is_another_posture_of_the_pose() {
        let robot = Robot::load(adwi_robot::model::shipped_file("iiwa14", "robot.toml")).unwrap();
        let o = PlanOptions {
            boxes_mm: vec![([400.0, -200.0, 300.0], [600.0, 200.0, 600.0])],
            tracker: None,
            orientations: Some(AllowedOrientations {
                abc_deg: vec![[0.0, 180.0, 0.0]],
                tolerance_deg: 5.0,
            }),
            branches: Branches::All,
            ..options(10, 60)
        };
        let (pool, _) = candidates(&robot, &o, &|_| {}).unwrap();
        let mut pairs = 0;
        for w in pool.windows(2) {
            if w[0].workspace && !w[1].workspace {
                pairs += 1;
                assert!(distance(w[0].position_mm, w[1].position_mm) < 1e-3);
                assert!(travel(&robot, &w[0].joints, &w[1].joints) > 1e-3);
                assert!(robot.within_limits(&w[1].joints));
            }
        }
        assert!(pairs > 5, "{pairs} poses with another posture");
    }

    /// A constant MPE weighs every pose alike: the same poses, the variances σ² times the
    /// per-σ² ones. A steep MPE against the distance draws the plan toward the tracker:
    /// the poses it weighs down are the far ones.
    #[test]
    fn the_tracker_weighs_far_poses_down() {
        let robot = ur5();
        let with = |mpe_um: Option<[f64; 2]>| PlanOptions {
            tracker: Some(TrackerSight {
                position_mm: [2000.0, 0.0, 500.0],
                range_mm: [500.0, 3000.0],
                sight_cone_deg: Some(70.0),
                mpe_um,
            }),
            coverage_weight: 0.0,
            ..options(20, 300)
        };
        let plain = plan(&robot, &with(None), &|_, _| {}, &|_| {}).unwrap();
        let flat = plan(&robot, &with(Some([20.0, 0.0])), &|_, _| {}, &|_| {}).unwrap();
        assert_eq!(plain.poses, flat.poses);
        let sigma2 = 0.01_f64.powi(2);
        for (a, b) in [
            (plain.mean_variance, flat.mean_variance),
            (plain.variance_bound, flat.variance_bound),
            (plain.random[1].mean_variance, flat.random[1].mean_variance),
        ] {
            assert!((a * sigma2 - b).abs() < 1e-6 * b, "{a} σ² against {b} mm²");
        }
        assert_eq!(flat.tracker_sigma_mm, Some([0.01, 0.01]));
        // The observability indices are the Jacobian's, unweighted.
        let (a, b) = (
            plain.planned.observability.unwrap(),
            flat.planned.observability.unwrap(),
        );
        for (x, y) in [
            (a.o1, b.o1),
            (a.o3, b.o3),
            (a.noise_amplification, b.noise_amplification),
        ] {
            assert!((x - y).abs() < 1e-9 * x, "{x} against {y}");
        }
        let steep = plan(&robot, &with(Some([1.0, 200.0])), &|_, _| {}, &|_| {}).unwrap();
        let reach = |p: &Plan| {
            p.poses
                .iter()
                .map(|q| distance(q.position_mm, [2000.0, 0.0, 500.0]))
                .sum::<f64>()
                / p.poses.len() as f64
        };
        assert!(
            reach(&steep) < reach(&plain) - 50.0,
            "{} mm against {} mm",
            reach(&steep),
            reach(&plain)
        );
        let [near, far] = steep.tracker_sigma_mm.unwrap();
        assert!(near < far);
    }

    #[test]
    fn tracker_mpe_and_branches_are_checked_before_any_work() {
        let mut o = options(5, 50);
        o.tracker.as_mut().unwrap().mpe_um = Some([-1.0, 6.0]);
        let e = check_options(&o).unwrap_err();
        assert!(e.to_string().contains("tracker_mpe_um"), "{e}");
        o.tracker.as_mut().unwrap().mpe_um = Some([15.0, f64::NAN]);
        assert!(check_options(&o).is_err());
        o.tracker.as_mut().unwrap().mpe_um = Some([15.0, 6.0]);
        check_options(&o).unwrap();
        o.branches = Branches::All;
        let e = check_options(&o).unwrap_err();
        assert!(e.to_string().contains("branches"), "{e}");
    }
}
