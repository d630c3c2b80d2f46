//! What a query answers: [`Correction`] and [`Compensation`], with a [`Status`] that says
//! whether the answer holds, for a [`Target`].

/// What a query's answer means.
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Status {
    /// The correction was predicted from at least one admissible neighbour.
    Ok = 0,
    /// The target lies outside the table's grid; the correction is zero.
    OutsideGrid = 1,
    /// No sample is admissible for the target; the correction is zero.
    NoAdmissibleNeighbour = 2,
    /// The target is not finite (NaN or infinite coordinates); the correction is zero.
    InvalidInput = 3,
    /// The table is a hybrid table (a calibrated kinematic model plus residuals), whose
    /// correction depends on the joint angles: query it with
    /// [`crate::Table::query_with_joints`]. The correction is zero.
    MissingJoints = 4,
    /// The prediction came out non-finite (NaN or infinite). A validated table gives this
    /// only in degenerate geometry, such as a target and a sample both within about
    /// 1e-160 mm of the base origin, where the approximation degrees overflow; answered
    /// instead of a correction no robot can be commanded with. The correction is zero.
    NumericalFailure = 5,
    /// The served field is not defined in the target's cell: the method has no admissible
    /// sample at one of the cell's corners, and the field is never extrapolated. The exact
    /// tier ([`crate::Table::exact`]) may still answer there. The correction is zero.
    UncoveredCell = 6,
    /// A hybrid table was given joint values whose nominal forward kinematics puts the tool
    /// farther from the target than [`crate::Table::joints_tolerance_mm`]: joints in
    /// degrees where radians are taken (or the reverse), or the joints of another target.
    /// The correction would be the model's at one pose plus the residual at another, so
    /// none is given. The correction is zero.
    JointsMismatch = 7,
}

impl Status {
    /// A short lowercase name, as the CLI prints it.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::OutsideGrid => "outside_grid",
            Status::NoAdmissibleNeighbour => "no_neighbour",
            Status::InvalidInput => "invalid_input",
            Status::MissingJoints => "missing_joints",
            Status::NumericalFailure => "numerical_failure",
            Status::UncoveredCell => "uncovered_cell",
            Status::JointsMismatch => "joints_mismatch",
        }
    }
}

/// How much of a hybrid table's residual field a correction holds: the calibrated model
/// answers everywhere, the residual where the samples are, fading to zero beyond them
/// (docs/runtime.md, "The residual flag"; [`crate::served`] has the fade). A
/// position-only table's answers, and a hybrid table's exact tier where the method
/// answers, are [`Residual::Full`].
#[repr(u8)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Residual {
    /// The whole residual: inside the grid, every corner blended had a value (the exact
    /// tier: the method answered). Also what a failed query carries (all fields zero).
    #[default]
    Full = 0,
    /// Part of it: a corner without a value contributed zero, the target is outside the
    /// grid within the fade length, or (format version 6) a joint lies within
    /// [`crate::joint_terms::RESIDUAL_FADE_RAD`] beyond the angles the samples span: the
    /// residual is scaled down.
    Faded = 1,
    /// None: the correction is the calibrated model's alone (beyond the fade, a
    /// configuration no sample has, a joint beyond the samples' angles and the fade, or no
    /// neighbour for the exact tier).
    ModelOnly = 2,
}

impl Residual {
    /// Every flag, indexed by its code (`Residual as u8`).
    pub const ALL: [Residual; 3] = [Residual::Full, Residual::Faded, Residual::ModelOnly];

    /// A short lowercase name, as the CLI prints it.
    pub fn as_str(self) -> &'static str {
        match self {
            Residual::Full => "full",
            Residual::Faded => "faded",
            Residual::ModelOnly => "model_only",
        }
    }
}

/// A target: where the controller wants the tool to be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Target {
    /// Nominal position, mm, base frame: of the table's point, or of the TCP `tcp_mm`
    /// when one is named.
    pub position_mm: [f64; 3],
    /// The inverse-kinematics configuration the controller will use, if known: samples
    /// of another configuration are then not admissible.
    pub config: Option<u8>,
    /// The tool's nominal orientation at the target, rotation vector, rad, base frame, if
    /// known. A position-only table checks it against the orientations its samples had
    /// ([`Evidence::ORIENTATION`]); a hybrid table takes the orientation from the joint
    /// values instead.
    pub rotation_rad: Option<[f64; 3]>,
    /// The TCP the target is for, mm, in the flange frame, when it is not the point the
    /// table's samples measured. A hybrid table then answers the error at this TCP: its
    /// model's position error at the measured point plus its rotation error turning the
    /// lever from that point to the TCP ([`crate::Table::query_with_joints`]). A table
    /// that cannot carry the lever says so ([`Evidence::TCP`]).
    pub tcp_mm: Option<[f64; 3]>,
}

impl Target {
    /// A target given by position alone.
    pub fn at(position_mm: [f64; 3]) -> Target {
        Target {
            position_mm,
            config: None,
            rotation_rad: None,
            tcp_mm: None,
        }
    }

    /// This target in configuration `config`.
    pub fn with_config(self, config: Option<u8>) -> Target {
        Target { config, ..self }
    }

    /// This target with the tool's nominal orientation (rotation vector, rad, base frame).
    pub fn with_rotation(self, rotation_rad: [f64; 3]) -> Target {
        Target {
            rotation_rad: Some(rotation_rad),
            ..self
        }
    }

    /// This target for the TCP at `tcp_mm` in the flange frame ([`Target::tcp_mm`]).
    pub fn with_tcp(self, tcp_mm: [f64; 3]) -> Target {
        Target {
            tcp_mm: Some(tcp_mm),
            ..self
        }
    }
}

/// Where an answer lies beyond what the table's samples cover, one bit a reason; empty
/// when it lies within (docs/runtime.md, "Evidence"). The positions the samples span are
/// the grid and the residual flag's ([`Residual`]); these are the rest.
///
/// A flagged answer is still the table's best, and continuous across the evidence's edge:
/// on a hybrid table the calibrated model carries it beyond the samples; on a
/// position-only table nothing does, and `tablec compensate` refuses such targets unless
/// told otherwise.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Evidence(pub u8);

impl Evidence {
    /// Within the samples' evidence, as far as the query says (no bit set).
    pub const WITHIN: Evidence = Evidence(0);
    /// The tool's approach axis at the target is farther from every sample's than the
    /// table's recorded spread ([`crate::format::ApproachCone`]) plus
    /// [`crate::format::ORIENTATION_MARGIN_RAD`].
    pub const ORIENTATION: Evidence = Evidence(1);
    /// A TCP was named that the table cannot relate to its measured point by its samples'
    /// evidence: more than [`crate::format::TCP_MARGIN_MM`] from its point on a
    /// position-only table (no model to turn the lever) or on a hybrid table whose samples
    /// measured position alone (its model's rotation error, which turns the lever, is not
    /// determined by them: docs/runtime.md, "Another TCP"), or any TCP on a table that
    /// does not record where its point is on the flange.
    pub const TCP: Evidence = Evidence(2);
    /// A joint whose joint-space terms the model carries ([`crate::joint_terms`]) is
    /// commanded more than [`crate::joint_terms::TERMS_MARGIN_RAD`] beyond the angles the
    /// terms were identified over, around the circle ([`crate::joint_terms::beyond_range`]):
    /// the model holds the term at its range's end there, a value no sample measured.
    pub const JOINTS: Evidence = Evidence(4);
    /// Every bit defined.
    pub const KNOWN: u8 = 7;

    /// Whether no bit is set.
    pub fn is_within(self) -> bool {
        self.0 == 0
    }

    /// Whether every bit of `other` is set.
    pub fn contains(self, other: Evidence) -> bool {
        self.0 & other.0 == other.0
    }

    /// The bits of both.
    #[must_use]
    pub fn with(self, other: Evidence) -> Evidence {
        Evidence(self.0 | other.0)
    }

    /// A short name, as the CLI prints it: `within`, or the reasons joined by `+` in the
    /// order of their bits (`orientation`, `tcp`, `joints`, `orientation+tcp`, ...).
    pub fn as_str(self) -> &'static str {
        match self.0 & Evidence::KNOWN {
            0 => "within",
            1 => "orientation",
            2 => "tcp",
            3 => "orientation+tcp",
            4 => "joints",
            5 => "orientation+joints",
            6 => "tcp+joints",
            _ => "orientation+tcp+joints",
        }
    }
}

/// The predicted error at a target: where the robot will land relative to where it was
/// told to go. Command `target − position_error_mm` to land on the target (to first
/// order; [`crate::Table::compensate`] solves it exactly).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction {
    /// Predicted position error (actual − nominal), mm, base frame.
    pub position_error_mm: [f64; 3],
    /// Predicted orientation error, rotation vector of `R_actual · R_nominalᵀ`, rad, base
    /// frame; zero when the table's samples measured none
    /// ([`crate::Table::has_orientation`]), a hybrid table's too: positions at one point do
    /// not determine its model's rotation error (docs/runtime.md, "Another TCP").
    pub orientation_error_rad: [f64; 3],
    /// The number of neighbours whose errors were weighted (the exact tier), or of nodes
    /// blended (the served tier: 8).
    pub neighbours: u32,
    /// Whether the prediction holds; every other field is zero unless this is `Ok`.
    pub status: Status,
    /// How much of a hybrid table's residual the correction holds ([`Residual::Full`] for
    /// a position-only table); meaningful only when `status` is `Ok`.
    pub residual: Residual,
    /// Where the answer lies beyond the samples' evidence ([`Evidence`]); meaningful only
    /// when `status` is `Ok`.
    pub evidence: Evidence,
}

impl Correction {
    pub(crate) fn failed(status: Status) -> Correction {
        Correction {
            position_error_mm: [0.0; 3],
            orientation_error_rad: [0.0; 3],
            neighbours: 0,
            status,
            residual: Residual::Full,
            evidence: Evidence::WITHIN,
        }
    }

    /// A hybrid table's answer where its residual has nothing: the model part (added by
    /// the caller) alone.
    pub(crate) fn model_only() -> Correction {
        Correction {
            residual: Residual::ModelOnly,
            ..Correction::failed(Status::Ok)
        }
    }

    /// The answer of these parts, [`Status::Ok`], or [`Status::NumericalFailure`] if a
    /// value is not finite: [`Correction::finite_or_failure`] of the correction they make,
    /// written for a query's fast path so that the answer's fields are stored once, where
    /// the caller wants them (a correction built whole and then checked was copied, its
    /// last fields reloaded in a wider piece than they were stored in: a stall of the
    /// processor's store forwarding).
    #[inline(always)]
    pub(crate) fn ok_if_finite(
        position_error_mm: [f64; 3],
        orientation_error_rad: [f64; 3],
        neighbours: u32,
        residual: Residual,
        evidence: Evidence,
    ) -> Correction {
        if !all_finite(position_error_mm, orientation_error_rad) {
            return Correction::failed(Status::NumericalFailure);
        }
        Correction {
            position_error_mm,
            orientation_error_rad,
            neighbours,
            status: Status::Ok,
            residual,
            evidence,
        }
    }

    /// This correction, or [`Status::NumericalFailure`] if it claims [`Status::Ok`] with
    /// a non-finite value: the last line of defence of every query path, so that no caller
    /// is ever told to command a NaN.
    #[inline]
    pub(crate) fn finite_or_failure(self) -> Correction {
        let finite = all_finite(self.position_error_mm, self.orientation_error_rad);
        if self.status == Status::Ok && !finite {
            return Correction::failed(Status::NumericalFailure);
        }
        self
    }
}

/// Whether all six values are finite, tested together: no early exit to branch on value
/// by value, and inlined (an iterator's `all` here was a call on every query).
#[inline(always)]
fn all_finite(a: [f64; 3], b: [f64; 3]) -> bool {
    let f = f64::is_finite;
    f(a[0]) & f(a[1]) & f(a[2]) & f(b[0]) & f(b[1]) & f(b[2])
}

impl Compensation {
    /// This compensation, with its correction turned into [`Status::NumericalFailure`]
    /// (and `converged` false) if it claims [`Status::Ok`] with a non-finite command or
    /// residual.
    #[inline]
    pub(crate) fn finite_or_failure(mut self) -> Compensation {
        let values = (self.command_position_mm.iter())
            .chain(&self.command_rotation_rad)
            .chain([&self.residual_mm]);
        if self.correction.status == Status::Ok && !values.into_iter().all(|v| v.is_finite()) {
            self.correction = Correction::failed(Status::NumericalFailure);
            self.converged = false;
        }
        self
    }
}

/// The fixed point's usual tolerance, mm: a command is accepted once the table predicts it
/// lands within this of the target (far below any robot's repeatability). tablec, the
/// Python package and program compensation all use it.
pub const COMPENSATE_TOLERANCE_MM: f64 = 1e-6;
/// The fixed point's usual iteration bound: it contracts by the error's gradient (a few per
/// cent per millimetre), so it converges in a handful; the bound only ends a table that
/// does not.
pub const COMPENSATE_ITERATIONS: u32 = 50;

/// The command that makes the robot land on a target, found by fixed-point iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compensation {
    /// The position to command, mm, base frame: `command + error(command) = target`.
    pub command_position_mm: [f64; 3],
    /// The rotation to apply to the target orientation, rotation vector, rad, base frame:
    /// command `R_cmd = Exp(command_rotation_rad) · R_target`. Zero without orientation.
    pub command_rotation_rad: [f64; 3],
    /// The correction predicted at the command.
    pub correction: Correction,
    /// Iterations used (queries made).
    pub iterations: u32,
    /// Whether `|command + error(command) − target| ≤ tolerance` was reached.
    pub converged: bool,
    /// `|command + error(command) − target|` at the returned command, mm.
    pub residual_mm: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The joined test is the plain one on every kind of value a double can be, at each of
    /// the six places, and on pairs of them.
    #[test]
    fn all_finite_is_every_value_is_finite() {
        let specials = [
            0.0,
            -0.0,
            1.0,
            -2.5e-310,
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::MIN,
            f64::EPSILON,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
        ];
        let reference = |v: &[f64; 6]| v.iter().all(|x| x.is_finite());
        for (i, &x) in specials.iter().enumerate() {
            for (j, &y) in specials.iter().enumerate() {
                for place in 0..6 {
                    for other in 0..6 {
                        let mut v = [0.5, -3.0, 1e300, -1e-300, 7.0, f64::MAX];
                        v[place] = x;
                        v[other] = y;
                        let (a, b) = ([v[0], v[1], v[2]], [v[3], v[4], v[5]]);
                        assert_eq!(all_finite(a, b), reference(&v), "{i} {j} {place} {other}");
                    }
                }
            }
        }
    }
}
