//! Whether samples agree with the robot file they are identified with: the robot's
//! nominal forward kinematics at each sample's joint values must put the tool near the
//! sample's commanded position.
//!
//! Samples whose joints are radians read as degrees, positions in metres, or another
//! robot's file all read without a single bad field, and an identification then fits
//! nonsense that a table serves with confidence. A hybrid table's query refuses joint
//! values that put the nominal tool farther than its joints tolerance from the target
//! (`adwi_runtime::Table::joints_tolerance_mm`, never less than [`MAX_NOMINAL_MISS_MM`]);
//! the samples a table is built from are held to the same rule, before any
//! identification:
//!
//! - base-frame samples ([`check_base_frame`]): the distance from the robot file's
//!   nominal TCP at the sample's joints (its base and tool included) to the sample's
//!   commanded `x,y,z`;
//! - tracker-frame measurements ([`check_registered`]): their nominal positions are the
//!   forward kinematics by construction, so the check is made after the rigid
//!   registration, on the distance from each measured position to the registered robot's
//!   prediction (the registered sample's error).
//!
//! A real robot misses by a few millimetres; a unit or robot mistake by hundreds. When
//! most samples miss ([`Disagreement::Systematic`]), the usual mistakes are tried on a
//! subset of the samples — revolute joints in the other angle unit, positions in metres or
//! in millimetres read as metres, both; for base-frame samples also another base frame (a
//! rigid fit) and another tool (a least-squares tool offset) — and the one that fits is
//! named. When a few samples miss among good ones ([`Disagreement::Outliers`]), they are
//! named by line. Either is refused: nothing is dropped silently.

use std::path::{Path, PathBuf};

use adwi_runtime::model::PreparedModel;
use adwi_samples::{Joints, Measurements, SampleSet};
use nalgebra::{Matrix3, Vector3};
use rayon::iter::{IntoParallelIterator, ParallelIterator};

use crate::register::{register, RegisterOptions};
use adwi_robot::model::{isometry_from_transform, JointKind};
use adwi_robot::Robot;

/// The largest distance from a sample's commanded position to the nominal TCP at its
/// joints, mm: the floor of the runtime's joints tolerance
/// (`adwi_runtime::served::fade_length_mm`), ten times a real robot's positioning error
/// and a tenth of what a unit or robot mistake makes.
pub const MAX_NOMINAL_MISS_MM: f64 = 20.0;

/// How many samples the alternatives are tried on (evenly strided): enough for a median,
/// cheap for a million samples.
const DIAGNOSIS_SAMPLES: usize = 500;

/// How many missing samples a message lists by line.
const LISTED: usize = 5;

/// One sample's miss.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Miss {
    /// The sample's source line.
    pub line: u64,
    /// How far the nominal TCP at its joints lies from its commanded (or measured)
    /// position, mm; infinite when the kinematics overflowed.
    pub miss_mm: f64,
}

/// A mistake in how samples were read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnitMistake {
    /// Revolute joint values in radians, read as degrees.
    JointsInRadians,
    /// Revolute joint values in degrees, read as radians.
    JointsInDegrees,
    /// Positions in metres, read as millimetres.
    PositionsInMetres,
    /// Positions in millimetres, read as metres.
    PositionsInMillimetres,
}

impl UnitMistake {
    /// The factor from the values as read to the values as meant.
    fn factor(self) -> f64 {
        match self {
            // Read as degrees, converted to radians: the file's number times π/180.
            UnitMistake::JointsInRadians => 180.0 / std::f64::consts::PI,
            UnitMistake::JointsInDegrees => std::f64::consts::PI / 180.0,
            UnitMistake::PositionsInMetres => 1000.0,
            UnitMistake::PositionsInMillimetres => 1e-3,
        }
    }

    fn is_joints(self) -> bool {
        matches!(
            self,
            UnitMistake::JointsInRadians | UnitMistake::JointsInDegrees
        )
    }

    /// The reading, in words.
    fn what(self) -> &'static str {
        match self {
            UnitMistake::JointsInRadians => "the joint values in radians",
            UnitMistake::JointsInDegrees => "the joint values in degrees",
            UnitMistake::PositionsInMetres => "the positions in metres",
            UnitMistake::PositionsInMillimetres => "the positions in millimetres",
        }
    }

    /// What to do about it.
    fn fix(self) -> &'static str {
        match self {
            UnitMistake::JointsInRadians => {
                "give the joint columns the unit rad (j1=COLUMN:rad, ... or j1:rad, ... in \
                 --columns)"
            }
            UnitMistake::JointsInDegrees => {
                "give the joint columns the unit deg (j1=COLUMN:deg, ... in --columns)"
            }
            UnitMistake::PositionsInMetres => {
                "give the position columns the unit m (x=COLUMN:m, ... in --columns, or \
                 --length-unit m)"
            }
            UnitMistake::PositionsInMillimetres => {
                "give the position columns the unit mm (x=COLUMN:mm, ... in --columns)"
            }
        }
    }
}

/// A reading of the samples under which the robot file fits them.
#[derive(Debug, Clone, PartialEq)]
pub enum Reading {
    /// The values in other units: one mistake, or one of the joints' and one of the
    /// positions'.
    Units(Vec<UnitMistake>),
    /// The commanded positions in another frame than the robot file's base: a rigid
    /// transform of the nominal TCP positions fits them.
    Frame {
        /// The transform's translation, mm.
        translation_mm: [f64; 3],
        /// Its rotation angle, degrees.
        rotation_deg: f64,
    },
    /// The commanded positions of another tool than the robot file's: a tool offset on
    /// the flange fits them.
    Tool {
        /// The tool's translation in the flange frame that fits, mm.
        translation_mm: [f64; 3],
    },
}

/// A reading that fits, and how well, on the samples it was tried on.
#[derive(Debug, Clone, PartialEq)]
pub struct Fitting {
    /// The reading.
    pub reading: Reading,
    /// The median miss under it, mm.
    pub median_mm: f64,
    /// The worst miss under it, mm.
    pub worst_mm: f64,
}

/// How well samples the robot file fits agree with it: their misses' figures.
#[derive(Debug, Clone, PartialEq)]
pub struct Agreement {
    /// Samples compared (none without joint values).
    pub samples: usize,
    /// The median miss, mm.
    pub median_mm: f64,
    /// The worst miss, when there were samples.
    pub worst: Option<Miss>,
    /// Another tool or base frame than the robot file's under which every sample fits,
    /// when the robot file's own does not: the identification takes it up (its tool and
    /// base parameters; an error model does not depend on a constant offset), so the
    /// samples are accepted and the caller warns.
    pub reading: Option<Fitting>,
}

/// The frame the samples' positions were compared in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compared {
    /// The robot's base frame: nominal TCP at the joints against the commanded position.
    Base,
    /// A tracker's frame, after the rigid registration: the registered robot's prediction
    /// against the measured position.
    Tracker,
}

/// Samples the robot file does not fit: refused before any identification (module docs).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Disagreement {
    /// Most samples miss: a unit, a robot file or a column mapping that is not the
    /// samples'.
    #[error("{}", systematic_text(self))]
    Systematic {
        /// The samples file.
        path: PathBuf,
        /// How the positions were compared.
        compared: Compared,
        /// Samples that miss by more than [`MAX_NOMINAL_MISS_MM`].
        missed: usize,
        /// Samples compared.
        samples: usize,
        /// The median miss, mm.
        median_mm: f64,
        /// The worst miss.
        worst: Miss,
        /// The reading that fits, when one of the usual mistakes explains the misses.
        fitting: Option<Box<Fitting>>,
    },
    /// A few samples miss among samples that fit: damaged or misplaced rows.
    #[error("{}", outliers_text(self))]
    Outliers {
        /// The samples file.
        path: PathBuf,
        /// How the positions were compared.
        compared: Compared,
        /// Samples compared.
        samples: usize,
        /// The median miss of all samples, mm.
        median_mm: f64,
        /// Every sample that misses by more than [`MAX_NOMINAL_MISS_MM`], in file order.
        outliers: Vec<Miss>,
    },
}

impl std::fmt::Display for Fitting {
    /// The reading in words, with its figures: what a warning about accepted samples says.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let figures = format!(
            "median miss {} mm, worst {} mm",
            mm(self.median_mm),
            mm(self.worst_mm)
        );
        match &self.reading {
            Reading::Units(mistakes) => {
                let whats: Vec<&str> = mistakes.iter().map(|m| m.what()).collect();
                write!(f, "with {} ({figures})", whats.join(" and "))
            }
            Reading::Frame {
                translation_mm: t,
                rotation_deg,
                ..
            } => write!(
                f,
                "in a frame {}, {}, {} mm and {rotation_deg:.2}° from the robot file's base \
                 ({figures})",
                mm(t[0]),
                mm(t[1]),
                mm(t[2])
            ),
            Reading::Tool { translation_mm: t } => write!(
                f,
                "with a tool at ({}, {}, {}) mm on the flange instead of the robot file's \
                 ({figures})",
                mm(t[0]),
                mm(t[1]),
                mm(t[2])
            ),
        }
    }
}

/// A length as messages write it: two decimals, exponent form beyond a million.
fn mm(value: f64) -> String {
    if value.is_finite() && value.abs() < 1e6 {
        format!("{value:.2}")
    } else {
        format!("{value:.3e}")
    }
}

/// What misses, and by more than what.
fn clause(compared: Compared) -> String {
    match compared {
        Compared::Base => format!(
            "the robot file's nominal forward kinematics at their joint values puts the tool \
             more than {MAX_NOMINAL_MISS_MM} mm from their commanded x,y,z"
        ),
        Compared::Tracker => format!(
            "registered to the robot file, the measured positions lie more than \
             {MAX_NOMINAL_MISS_MM} mm from the robot's prediction at their joint values"
        ),
    }
}

fn systematic_text(d: &Disagreement) -> String {
    let Disagreement::Systematic {
        path,
        compared,
        missed,
        samples,
        median_mm,
        worst,
        fitting,
    } = d
    else {
        return String::new();
    };
    let mut text = format!(
        "{}: {} for {missed} of {samples} samples (median {} mm, worst {} mm at line {})",
        path.display(),
        clause(*compared),
        mm(*median_mm),
        mm(worst.miss_mm),
        worst.line
    );
    match fitting.as_deref() {
        Some(Fitting {
            reading,
            median_mm,
            worst_mm,
        }) => {
            let figures = format!("median {} mm, worst {} mm", mm(*median_mm), mm(*worst_mm));
            match reading {
                Reading::Units(mistakes) => {
                    let whats: Vec<&str> = mistakes.iter().map(|m| m.what()).collect();
                    let fixes: Vec<&str> = mistakes.iter().map(|m| m.fix()).collect();
                    text.push_str(&format!(
                        ": they fit with {} ({figures}); {}",
                        whats.join(" and "),
                        fixes.join("; ")
                    ));
                }
                Reading::Frame {
                    translation_mm: t,
                    rotation_deg,
                    ..
                } => text.push_str(&format!(
                    ": a rigid transform of the robot's positions (translation {}, {}, {} mm, \
                     rotation {rotation_deg:.2}°) fits them ({figures}): the positions are in \
                     another frame than the robot file's base; give the base in the robot file, \
                     or read a tracker's frame with --measured-in tracker",
                    mm(t[0]),
                    mm(t[1]),
                    mm(t[2])
                )),
                Reading::Tool { translation_mm: t } => text.push_str(&format!(
                    ": a tool at ({}, {}, {}) mm on the flange fits them ({figures}): the \
                     samples' TCP is not the robot file's tool; give it in the robot file \
                     ([tool] translation_mm)",
                    mm(t[0]),
                    mm(t[1]),
                    mm(t[2])
                )),
            }
        }
        None => text.push_str(match compared {
            Compared::Base => {
                ": neither the joints in the other angle unit, the positions in metres, another \
                 base frame nor another tool fits them; is the robot file this robot's, and does \
                 the column map (--columns) take x,y,z and j1..jn from the right columns, in \
                 order and with their signs?"
            }
            Compared::Tracker => {
                ": neither the joints in the other angle unit nor the positions in metres fits \
                 them; is the robot file this robot's, are the rows one tracker frame's, and \
                 does the column map (--columns) take mx,my,mz and j1..jn from the right \
                 columns, in order and with their signs?"
            }
        }),
    }
    text
}

fn outliers_text(d: &Disagreement) -> String {
    let Disagreement::Outliers {
        path,
        compared,
        samples,
        median_mm,
        outliers,
    } = d
    else {
        return String::new();
    };
    let listed: Vec<String> = outliers
        .iter()
        .take(LISTED)
        .map(|m| format!("line {} ({} mm)", m.line, mm(m.miss_mm)))
        .collect();
    let more = match outliers.len().saturating_sub(LISTED) {
        0 => String::new(),
        n => format!(" and {n} more"),
    };
    format!(
        "{}: {} for {} of {samples} samples, where the median sample misses by {} mm: \
         {}{more}; correct or remove these rows",
        path.display(),
        clause(*compared),
        outliers.len(),
        mm(*median_mm),
        listed.join(", ")
    )
}

/// The median of `values` (reordered in place), 0 for none.
fn median(values: &mut [f64]) -> f64 {
    // The value a sort would put there, found without sorting a million misses.
    if values.is_empty() {
        return 0.0;
    }
    let middle = values.len() / 2;
    *values.select_nth_unstable_by(middle, f64::total_cmp).1
}

/// The robot's nominal chain as the query path walks it ([`PreparedModel::at_position`]'s
/// `nominal_tcp_mm`: the chain's own forward kinematics to 4e-12 mm, in a third of its
/// time), rigid as [`Robot::tcp_pose`] is; `None` where the runtime cannot prepare it.
fn rigid_walk(robot: &Robot) -> Option<PreparedModel> {
    let mut rigid = *robot.chain();
    rigid.compliance = None;
    PreparedModel::new(rigid, rigid)
}

/// Median and worst of misses.
fn figures(misses: &[f64]) -> (f64, f64) {
    let worst = misses.iter().copied().fold(0.0, f64::max);
    (median(&mut misses.to_vec()), worst)
}

/// A miss, infinite when not a number (an overflowed kinematics).
fn finite_or_infinite(d: f64) -> f64 {
    if d.is_nan() {
        f64::INFINITY
    } else {
        d
    }
}

/// Evenly strided indices of at most [`DIAGNOSIS_SAMPLES`] of `n`.
fn subset(n: usize) -> Vec<usize> {
    let stride = n.div_ceil(DIAGNOSIS_SAMPLES).max(1);
    (0..n).step_by(stride).collect()
}

/// Judges `misses` (one per sample, with its line): their figures when none exceeds
/// [`MAX_NOMINAL_MISS_MM`], otherwise the refusal, systematic when the median does
/// (`diagnose` then names the reading that fits).
fn judge(
    path: &Path,
    compared: Compared,
    misses: Vec<Miss>,
    diagnose: impl FnOnce() -> Option<Fitting>,
) -> Result<Agreement, Disagreement> {
    let mut all: Vec<f64> = misses.iter().map(|m| m.miss_mm).collect();
    let median_mm = median(&mut all);
    let missing: Vec<Miss> = misses
        .iter()
        .copied()
        .filter(|m| m.miss_mm > MAX_NOMINAL_MISS_MM)
        .collect();
    if missing.is_empty() {
        return Ok(Agreement {
            samples: misses.len(),
            median_mm,
            worst: misses
                .iter()
                .copied()
                .max_by(|a, b| a.miss_mm.total_cmp(&b.miss_mm)),
            reading: None,
        });
    }
    if median_mm > MAX_NOMINAL_MISS_MM {
        let worst = missing
            .iter()
            .copied()
            .max_by(|a, b| a.miss_mm.total_cmp(&b.miss_mm))
            .expect("one at least");
        return Err(Disagreement::Systematic {
            path: path.to_path_buf(),
            compared,
            missed: missing.len(),
            samples: misses.len(),
            median_mm,
            worst,
            fitting: diagnose().map(Box::new),
        });
    }
    Err(Disagreement::Outliers {
        path: path.to_path_buf(),
        compared,
        samples: misses.len(),
        median_mm,
        outliers: missing,
    })
}

/// The unit mistakes tried: each alone, then a joints' one with a positions' one.
fn unit_readings() -> Vec<Vec<UnitMistake>> {
    use UnitMistake::*;
    let mut out: Vec<Vec<UnitMistake>> = [
        JointsInRadians,
        JointsInDegrees,
        PositionsInMetres,
        PositionsInMillimetres,
    ]
    .into_iter()
    .map(|m| vec![m])
    .collect();
    for j in [JointsInRadians, JointsInDegrees] {
        for p in [PositionsInMetres, PositionsInMillimetres] {
            out.push(vec![j, p]);
        }
    }
    out
}

/// `joints` with the revolute joints' values scaled by the joint mistake among
/// `mistakes`, if any.
fn scaled_joints(robot: &Robot, joints: &[f64], mistakes: &[UnitMistake]) -> Vec<f64> {
    let factor = mistakes
        .iter()
        .find(|m| m.is_joints())
        .map_or(1.0, |m| m.factor());
    joints
        .iter()
        .enumerate()
        .map(|(j, &v)| match robot.joint_kind(j) {
            JointKind::Revolute => v * factor,
            JointKind::Prismatic => v,
        })
        .collect()
}

/// The positions' factor of `mistakes`.
fn position_factor(mistakes: &[UnitMistake]) -> f64 {
    mistakes
        .iter()
        .find(|m| !m.is_joints())
        .map_or(1.0, |m| m.factor())
}

/// The fitting with the smallest median, if it fits: its median within
/// [`MAX_NOMINAL_MISS_MM`] and within a tenth of the spread of the positions it was fitted
/// to (`spread_mm`, beside each: positions shrunk to a point fit anything a registration
/// can move).
fn best(fittings: impl IntoIterator<Item = (Fitting, f64)>) -> Option<Fitting> {
    fittings
        .into_iter()
        .filter(|(f, spread_mm)| {
            f.median_mm <= MAX_NOMINAL_MISS_MM && f.median_mm * 10.0 <= *spread_mm
        })
        .map(|(f, _)| f)
        .min_by(|a, b| a.median_mm.total_cmp(&b.median_mm))
}

/// The RMS distance of `points` from their centre, mm.
fn spread_mm(points: impl Iterator<Item = Vector3<f64>> + Clone) -> f64 {
    let n = points.clone().count().max(1) as f64;
    let centre = points.clone().sum::<Vector3<f64>>() / n;
    (points.map(|p| (p - centre).norm_squared()).sum::<f64>() / n).sqrt()
}

/// Checks base-frame samples against `robot` (module docs): every sample's nominal TCP at
/// its joints within [`MAX_NOMINAL_MISS_MM`] of its commanded position; returns the
/// misses' figures. Samples without joint values, or with another count than the robot's
/// joints, are not checked here (the identification refuses them in its own words).
///
/// # Errors
///
/// [`Disagreement`], naming `path`, the figures and the reading that fits.
pub fn check_base_frame(
    robot: &Robot,
    samples: &SampleSet,
    path: &Path,
) -> Result<Agreement, Disagreement> {
    let Some(joints) = samples
        .joints
        .as_ref()
        .filter(|j| j.count() == robot.joint_count())
    else {
        return Ok(Agreement {
            samples: 0,
            median_mm: 0.0,
            worst: None,
            reading: None,
        });
    };
    let walk = rigid_walk(robot);
    let tcp = |q: &[f64]| -> Vector3<f64> {
        match walk.as_ref().and_then(|w| w.at_position(q)) {
            Some(at) => Vector3::from(at.nominal_tcp_mm),
            None => robot.tcp_pose(q).translation.vector,
        }
    };
    let miss = |q: &[f64], p: [f64; 3], scale: f64| -> f64 {
        finite_or_infinite((tcp(q) - Vector3::from(p) * scale).norm())
    };
    // Each sample's forward kinematics, on the thread pool (a million samples: a quarter
    // of a second on one thread); in sample order.
    let misses: Vec<Miss> = (0..samples.len())
        .into_par_iter()
        .map(|i| Miss {
            line: samples.lines[i],
            miss_mm: miss(joints.row(i), samples.nominal_mm[i], 1.0),
        })
        .collect();
    let judged = judge(path, Compared::Base, misses, || {
        diagnose_base(robot, joints, &samples.nominal_mm, &subset(samples.len()))
    });
    // Another tool: accepted when every sample fits with it, as the identification takes
    // the tool up. Another base frame is not: the positions would be in one frame and the
    // joints' forward kinematics in another, so that a hybrid table refuses its own
    // samples' poses and corrects a program's, written in the samples' frame, at other
    // joints than the controller's (a KR16 whose samples' frame lies 450 mm above its
    // robot file's base: 0.23 mm from its targets against 0.05 in the right frame).
    let Err(Disagreement::Systematic {
        fitting: Some(fitting),
        ..
    }) = &judged
    else {
        return judged;
    };
    let Reading::Tool { translation_mm } = fitting.reading else {
        return judged;
    };
    let under: Vec<Miss> = (0..samples.len())
        .into_par_iter()
        .map(|i| Miss {
            line: samples.lines[i],
            miss_mm: miss_with_tool(robot, translation_mm, joints.row(i), samples.nominal_mm[i]),
        })
        .collect();
    match judge(path, Compared::Base, under, || None) {
        Ok(agreement) => Ok(Agreement {
            reading: Some(fitting.as_ref().clone()),
            ..agreement
        }),
        Err(_) => judged,
    }
}

/// The miss of a sample at joints `q` commanded to `p` with another tool, at
/// `translation_mm` on the flange.
fn miss_with_tool(robot: &Robot, translation_mm: [f64; 3], q: &[f64], p: [f64; 3]) -> f64 {
    let flange = robot.tcp_pose(q) * isometry_from_transform(&robot.tool()).inverse();
    let at = flange.rotation * Vector3::from(translation_mm) + flange.translation.vector;
    finite_or_infinite((at - Vector3::from(p)).norm())
}

/// The reading of base-frame samples that fits (module docs), tried at `at`.
fn diagnose_base(
    robot: &Robot,
    joints: &Joints,
    nominal_mm: &[[f64; 3]],
    at: &[usize],
) -> Option<Fitting> {
    let fitting = |reading: Reading, misses: Vec<f64>| {
        let (median_mm, worst_mm) = figures(&misses);
        Fitting {
            reading,
            median_mm,
            worst_mm,
        }
    };
    let spread_at =
        |scale: f64| spread_mm(at.iter().map(|&i| Vector3::from(nominal_mm[i]) * scale));
    let units = unit_readings().into_iter().map(|mistakes| {
        let scale = position_factor(&mistakes);
        let misses = at
            .iter()
            .map(|&i| {
                let q = scaled_joints(robot, joints.row(i), &mistakes);
                let tcp = robot.tcp_pose(&q).translation.vector;
                finite_or_infinite((tcp - Vector3::from(nominal_mm[i]) * scale).norm())
            })
            .collect();
        (fitting(Reading::Units(mistakes), misses), spread_at(scale))
    });
    if let Some(found) = best(units) {
        return Some(found);
    }
    // Another frame or another tool, with the values as read.
    let tool = isometry_from_transform(&robot.tool()).inverse();
    let mut tcp = Vec::with_capacity(at.len());
    let mut flange = Vec::with_capacity(at.len());
    let mut target = Vec::with_capacity(at.len());
    for &i in at {
        let pose = robot.tcp_pose(joints.row(i));
        tcp.push(pose.translation.vector);
        flange.push(pose * tool);
        target.push(Vector3::from(nominal_mm[i]));
    }
    let mut fittings = Vec::new();
    if let Some((rotation, translation)) = rigid_fit(&tcp, &target) {
        let misses = tcp
            .iter()
            .zip(&target)
            .map(|(a, b)| finite_or_infinite((rotation * a + translation - b).norm()))
            .collect();
        // By atan2, finite at the identity, where `Rotation3::angle`'s arccosine of a
        // trace a rounding above 3 is NaN.
        let rows: [[f64; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| rotation[(i, j)]));
        let rotation_rad = adwi_runtime::kinematics::rotation_vector(&rows);
        fittings.push((
            fitting(
                Reading::Frame {
                    translation_mm: translation.into(),
                    rotation_deg: Vector3::from(rotation_rad).norm().to_degrees(),
                },
                misses,
            ),
            spread_at(1.0),
        ));
    }
    // The tool t minimising Σ |R_f t + p_f − target|²: the mean of R_fᵀ (target − p_f).
    let offset: Vector3<f64> = flange
        .iter()
        .zip(&target)
        .map(|(f, b)| f.rotation.inverse() * (b - f.translation.vector))
        .sum::<Vector3<f64>>()
        / at.len().max(1) as f64;
    if offset.iter().all(|v| v.is_finite()) {
        let misses = flange
            .iter()
            .zip(&target)
            .map(|(f, b)| {
                finite_or_infinite((f.rotation * offset + f.translation.vector - b).norm())
            })
            .collect();
        fittings.push((
            fitting(
                Reading::Tool {
                    translation_mm: offset.into(),
                },
                misses,
            ),
            spread_at(1.0),
        ));
    }
    best(fittings)
}

/// The rotation and translation that best map `from` onto `to` (Kabsch), `None` when the
/// points do not fix one or are not finite.
fn rigid_fit(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let n = from.len();
    if n < 3 {
        return None;
    }
    let centre = |p: &[Vector3<f64>]| p.iter().sum::<Vector3<f64>>() / n as f64;
    let (ca, cb) = (centre(from), centre(to));
    let h: Matrix3<f64> = from
        .iter()
        .zip(to)
        .map(|(a, b)| (a - ca) * (b - cb).transpose())
        .sum();
    if !h.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = h.try_svd(true, true, 1e-12, 100)?;
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut v = v_t.transpose();
    if (v * u.transpose()).determinant() < 0.0 {
        let mut column = v.column_mut(2);
        column *= -1.0;
    }
    let rotation = v * u.transpose();
    Some((rotation, cb - rotation * ca))
}

/// Checks tracker-frame samples after their registration (module docs): every registered
/// sample's error — the measured position against the registered robot's prediction —
/// within [`MAX_NOMINAL_MISS_MM`]; returns the misses' figures. `measurements` are the
/// rows the samples were registered from, on which the usual unit mistakes are tried by
/// registering them again.
///
/// # Errors
///
/// [`Disagreement`], naming `path`, the figures and the reading that fits.
pub fn check_registered(
    robot: &Robot,
    measurements: &Measurements,
    registered: &SampleSet,
    path: &Path,
) -> Result<Agreement, Disagreement> {
    let misses: Vec<Miss> = (0..registered.len())
        .map(|i| {
            let e = registered.error_mm[i];
            Miss {
                line: registered.lines[i],
                miss_mm: finite_or_infinite(Vector3::from(e).norm()),
            }
        })
        .collect();
    judge(path, Compared::Tracker, misses, || {
        diagnose_registered(robot, measurements)
    })
}

/// The unit mistake under which `measurements` register to `robot` within
/// [`MAX_NOMINAL_MISS_MM`], tried on a subset of their rows (positions only).
fn diagnose_registered(robot: &Robot, measurements: &Measurements) -> Option<Fitting> {
    if measurements.joints.count() != robot.joint_count() {
        return None;
    }
    let at = subset(measurements.len());
    let fittings = unit_readings().into_iter().filter_map(|mistakes| {
        let scale = position_factor(&mistakes);
        let mut joints = Joints::new(measurements.joints.count());
        for &i in &at {
            joints.push(&scaled_joints(robot, measurements.joints.row(i), &mistakes));
        }
        let rows = Measurements {
            joints,
            nominal_mm: None,
            nominal_rotation: None,
            measured_mm: at
                .iter()
                .map(|&i| measurements.measured_mm[i].map(|v| v * scale))
                .collect(),
            measured_rotation: None,
            config: None,
            lines: at.iter().map(|&i| measurements.lines[i]).collect(),
        };
        let registration = register(robot, &rows, &RegisterOptions::default()).ok()?;
        let samples = registration.to_samples(robot, &rows).ok()?;
        let misses: Vec<f64> = samples
            .error_mm
            .iter()
            .map(|e| finite_or_infinite(Vector3::from(*e).norm()))
            .collect();
        let (median_mm, worst_mm) = figures(&misses);
        let spread = spread_mm(rows.measured_mm.iter().map(|p| Vector3::from(*p)));
        Some((
            Fitting {
                reading: Reading::Units(mistakes),
                median_mm,
                worst_mm,
            },
            spread,
        ))
    });
    best(fittings)
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use adwi_robot::model::shipped_robot_path;

    /// The UR5 robot and its grid samples, as the README maps them.
    fn ur5() -> (Robot, SampleSet) {
        let robot = Robot::load(shipped_robot_path("ur5")).unwrap();
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tables/ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv");
        let map = adwi_samples::ColumnMap::parse(
            "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,j1=joint_1,j2=joint_2,j3=joint_3,\
             j4=joint_4,j5=joint_5,j6=joint_6",
        )
        .unwrap();
        (robot, adwi_samples::read_samples(&path, &map).unwrap())
    }

    /// Every shipped data set fits its robot file (no false refusal), with room: the UR5's
    /// measurements and the KR150-2's simulated samples in the base frame, the UR10's
    /// three tracker-frame series each registered on its own. Prints the figures.
    #[test]
    fn the_shipped_data_fit_their_robot_files() {
        let tables = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables");
        let read = adwi_samples::ReadOptions::default();
        let ur5_map = "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,j1=joint_1,j2=joint_2,\
                       j3=joint_3,j4=joint_4,j5=joint_5,j6=joint_6";
        let base = [
            (
                "ur5",
                "ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv",
                ur5_map,
            ),
            (
                "ur5",
                "ur5/measurements/3D_UR5_uncalibrated_random_cleaned.csv",
                ur5_map,
            ),
            ("kr150-2", "kr150-2/samples.csv", ""),
            ("kr150-2", "kr150-2/validation.csv", ""),
        ];
        let mut figures = Vec::new();
        for (robot, file, map) in base {
            let robot = Robot::load(shipped_robot_path(robot)).unwrap();
            let map = adwi_samples::ColumnMap::parse(map).unwrap();
            let samples = adwi_samples::read_samples(&tables.join(file), &map).unwrap();
            let agreement = check_base_frame(&robot, &samples, Path::new(file)).unwrap();
            figures.push((file, agreement));
        }
        let ur10 = Robot::load(shipped_robot_path("ur10")).unwrap();
        let ur10_map = adwi_samples::ColumnMap::parse(
            "j1=shoulder_pan_joint:rad,j2=shoulder_lift_joint:rad,j3=elbow_joint:rad,\
             j4=wrist_1_joint:rad,j5=wrist_2_joint:rad,j6=wrist_3_joint:rad,\
             mx=measurement_x,my=measurement_y,mz=measurement_z,\
             mex=measurement_rx:deg,mey=measurement_ry:deg,mez=measurement_rz:deg",
        )
        .unwrap();
        for file in [
            "ur10/measurements/Series_A/measurements_grid.csv",
            "ur10/measurements/Series_B/measurements_joint_configurations.csv",
            "ur10/measurements/Series_C/measurements_random_poses.csv",
        ] {
            let rows =
                adwi_samples::read_measurements(&tables.join(file), &ur10_map, &read).unwrap();
            let (_, samples) = crate::measured::Registered::from_measurements(
                Path::new(file),
                &rows,
                ur10.clone(),
            )
            .unwrap();
            let agreement = check_registered(&ur10, &rows, &samples, Path::new(file)).unwrap();
            figures.push((file, agreement));
        }
        for (file, a) in figures {
            let worst = a.worst.expect("samples compared");
            println!(
                "{file}: {} samples, median miss {:.4} mm, worst {:.4} mm (line {})",
                a.samples, a.median_mm, worst.miss_mm, worst.line
            );
            assert!(
                a.samples > 0 && worst.miss_mm < MAX_NOMINAL_MISS_MM / 2.0,
                "{file}"
            );
        }
    }

    /// The check's forward kinematics (the runtime's folded walk) is `Robot::tcp_pose`'s to
    /// a picometre, for every shipped robot (a compliance its file gives left out by both) at
    /// random joint values within two turns: the same misses, the same verdicts.
    #[test]
    fn the_checks_walk_is_the_robots_own_forward_kinematics() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        for name in ["ur5", "ur10", "kr150-2", "iiwa14"] {
            let robot = Robot::load(shipped_robot_path(name)).unwrap();
            let walk = rigid_walk(&robot).unwrap();
            for _ in 0..2000 {
                let q: Vec<f64> = (0..robot.joint_count())
                    .map(|_| rng.gen_range(-4.0 * PI..4.0 * PI))
                    .collect();
                let by_walk = walk.at_position(&q).unwrap().nominal_tcp_mm;
                let by_robot = robot.tcp_pose(&q).translation.vector;
                let gap = (Vector3::from(by_walk) - by_robot).norm();
                assert!(gap < 1e-9, "{name} {q:?}: {gap:e} mm");
            }
        }
    }

    /// Positions in another frame (shifted and turned, or shifted alone: a rotation of
    /// exactly none is named as 0.00°, never NaN) are refused with that frame named;
    /// positions of another tool are accepted with the tool named (the identification
    /// takes it up), and refused naming the row when a row is damaged besides.
    #[test]
    fn another_frame_is_refused_and_another_tool_accepted_both_named() {
        let (robot, samples) = ur5();
        for (angle, shift) in [(0.3, [100.0, -50.0, 30.0]), (0.0, [0.0, 0.0, -450.0])] {
            let turn = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), angle);
            let mut moved = samples.clone();
            for p in &mut moved.nominal_mm {
                *p = (turn * Vector3::from(*p) + Vector3::from(shift)).into();
            }
            let error = check_base_frame(&robot, &moved, Path::new("moved.csv")).unwrap_err();
            let Disagreement::Systematic {
                fitting: Some(fitting),
                ..
            } = &error
            else {
                panic!("{error:?}")
            };
            let Reading::Frame { rotation_deg, .. } = fitting.reading else {
                panic!("{error:?}")
            };
            assert!(
                (rotation_deg - angle.to_degrees()).abs() < 0.01,
                "{rotation_deg}"
            );
            let text = error.to_string();
            assert!(
                text.contains(&format!("rotation {:.2}°", angle.to_degrees()))
                    && text.contains("another frame than the robot file's base"),
                "{text}"
            );
        }

        let mut tooled = samples.clone();
        let joints = samples.joints.as_ref().unwrap();
        for (i, p) in tooled.nominal_mm.iter_mut().enumerate() {
            let flange = robot.tcp_pose(joints.row(i)).rotation;
            *p = (Vector3::from(*p) + flange * Vector3::new(0.0, 0.0, 150.0)).into();
        }
        let a = check_base_frame(&robot, &tooled, Path::new("tooled.csv")).unwrap();
        let Some(Fitting {
            reading: Reading::Tool { translation_mm },
            ..
        }) = &a.reading
        else {
            panic!("{a:?}")
        };
        assert!(
            (translation_mm[2] - 181.0).abs() < 0.1,
            "{translation_mm:?}"
        );
        let text = a.reading.as_ref().unwrap().to_string();
        assert!(
            text.starts_with("with a tool at (-0.00, 0.09, 181.00) mm on the flange instead"),
            "{text}"
        );
        // One row 100 mm off besides: refused, naming the tool that fits the others.
        tooled.nominal_mm[7][0] += 100.0;
        let e = check_base_frame(&robot, &tooled, Path::new("tooled.csv")).unwrap_err();
        assert!(
            e.to_string()
                .contains("a tool at (-0.00, 0.09, 181.00) mm on the flange fits"),
            "{e}"
        );
    }
}
