//! What a program's reader finds: its targets, each with the numbers that write it, the
//! frames it is commanded in, and what it says about the arm's configuration.

use nalgebra::Isometry3;

use crate::number::Number;

/// The units of a program's positions and joints: the sample files' own.
pub use adwi_samples::{AngleUnit, LengthUnit};

/// A program format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// KUKA KRL: a `.src` or a `.dat` file.
    Krl,
    /// ABB RAPID: a `.mod` (or `.modx`, `.prg`, `.sys`, `.sysx`) module.
    Rapid,
    /// Universal Robots URScript: a `.script` file.
    UrScript,
    /// A CSV of poses, as `tablec query --targets` reads them.
    Csv,
    /// G-code (ISO 6983): a `.nc`, `.ngc`, `.gcode` or `.tap` file.
    Gcode,
    /// Yaskawa INFORM: a `.jbi` job.
    Yaskawa,
    /// Fanuc TP in its ASCII form: a `.ls` program.
    Fanuc,
    /// Stäubli VAL3: an application (`.pjx`), its data (`.dtx`) corrected.
    Val3,
}

impl Format {
    /// Every format.
    pub const ALL: [Format; 8] = [
        Format::Krl,
        Format::Rapid,
        Format::UrScript,
        Format::Csv,
        Format::Gcode,
        Format::Yaskawa,
        Format::Fanuc,
        Format::Val3,
    ];

    /// The name the command line takes (`krl`, `rapid`, `urscript`, `csv`, `gcode`).
    pub fn name(self) -> &'static str {
        match self {
            Format::Krl => "krl",
            Format::Rapid => "rapid",
            Format::UrScript => "urscript",
            Format::Csv => "csv",
            Format::Gcode => "gcode",
            Format::Yaskawa => "yaskawa",
            Format::Fanuc => "fanuc",
            Format::Val3 => "val3",
        }
    }

    /// The format of a name as [`Format::name`] gives it.
    pub fn from_name(name: &str) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.name() == name)
    }

    /// The format of a file by its extension (case-insensitive): `.src`, `.dat` KRL;
    /// `.mod`, `.modx`, `.prg`, `.sys`, `.sysx` RAPID; `.script`, `.urscript` URScript; `.csv` CSV;
    /// `.nc`, `.ngc`, `.gcode`, `.tap` G-code; `.jbi` Yaskawa INFORM; `.ls` Fanuc TP; `.pjx`,
    /// `.dtx` a Stäubli VAL3 application.
    pub fn from_path(path: &std::path::Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "src" | "dat" => Format::Krl,
            "mod" | "modx" | "prg" | "sys" | "sysx" => Format::Rapid,
            "script" | "urscript" => Format::UrScript,
            "csv" => Format::Csv,
            "nc" | "ngc" | "gcode" | "tap" => Format::Gcode,
            "jbi" => Format::Yaskawa,
            "ls" => Format::Fanuc,
            "pjx" | "dtx" => Format::Val3,
            _ => return None,
        })
    }
}

/// A target of a program: where the TCP is told to go (a pose) or how the joints are told
/// to stand.
#[derive(Clone, Debug)]
pub struct ProgramTarget {
    /// Its name (a declared variable), or the instruction that writes it inline
    /// (`LIN`, `MoveL`, `movel`, `row`).
    pub name: String,
    /// The byte where it is written.
    pub offset: usize,
    /// What it is.
    pub kind: TargetKind,
    /// The frames it is commanded in, one per use the reader saw (none: the job's
    /// defaults).
    pub uses: Vec<FrameUse>,
    /// Why the reader leaves it unchanged, when it does: a motion whose target the program
    /// offsets, computes or names without declaring it, or a target beyond what a table
    /// answers (an external axis). `None`: the job corrects it.
    pub refused: Option<Refusal>,
}

/// Why a motion's target is reported and left unchanged rather than corrected: the
/// reader found the motion, but no command computed offline lands it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refusal {
    /// The kind of reason.
    pub reason: Reason,
    /// What, in the program's words (the expression, the frame, the axis).
    pub detail: String,
}

/// The kinds of [`Refusal`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Reason {
    /// An offset from a pose the controller knows only at run time (KRL `LIN_REL`, RAPID
    /// `Offs`/`RelTool`, URScript `pose_trans` of a target): one correction of the
    /// written numbers cannot hold for every pose it is added to.
    Relative,
    /// A target computed at run time (a function's result, a variable the program assigns
    /// as it runs).
    Dynamic,
    /// A frame the motion uses (a tool, a base or work object) whose value neither the
    /// program nor the job's options give.
    FrameUnknown,
    /// A target with an external axis (a linear track, a turntable) moved: where the robot
    /// or the work stands is not in the table.
    ExternalAxis,
    /// A call that looks like a motion but is not in the dialect's table of motions.
    UnknownMotion,
    /// A motion to a name declared neither in the file nor in its partner (a global of
    /// another module or of the controller's configuration).
    NotDeclared,
    /// A G-code arc whose centre, moved with its corrected ends, does not keep the arc
    /// within the tolerance of the corrected path (or whose path the table does not
    /// correct throughout).
    ArcTolerance,
    /// A target no motion instruction moves to, which the dialect leaves as written (a
    /// VAL3 point used only by other code, or by none).
    NotMoved,
}

impl Reason {
    /// Its name in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Reason::Relative => "relative",
            Reason::Dynamic => "dynamic",
            Reason::FrameUnknown => "frame_unknown",
            Reason::ExternalAxis => "external_axis",
            Reason::UnknownMotion => "unknown_motion",
            Reason::NotDeclared => "not_declared",
            Reason::ArcTolerance => "arc_tolerance",
            Reason::NotMoved => "not_moved",
        }
    }
}

impl Refusal {
    /// A refusal for `reason`, saying `detail`.
    pub fn new(reason: Reason, detail: impl Into<String>) -> Refusal {
        Refusal {
            reason,
            detail: detail.into(),
        }
    }
}

/// What a target is.
#[derive(Clone, Debug)]
pub enum TargetKind {
    /// A pose of the TCP in a work-object (base) frame.
    Cartesian(Box<CartesianTarget>),
    /// Joint values.
    Joints(JointTarget),
    /// A target the program writes only in part (a KRL aggregate without some of its
    /// coordinates: the controller takes the rest from where the robot stands), so no
    /// command can be computed for it; the text names what is missing.
    Incomplete(String),
    /// A motion whose target the file writes no numbers for (an expression, or a name it
    /// does not declare): always [`ProgramTarget::refused`], reported with the motion's
    /// place.
    Motion,
}

/// A Cartesian target's numbers.
#[derive(Clone, Debug)]
pub struct CartesianTarget {
    /// X, Y, Z.
    pub position: [Number; 3],
    /// Their unit.
    pub unit: LengthUnit,
    /// The orientation, when the program writes one.
    pub orientation: Option<Orientation>,
    /// What the program says about the arm's configuration.
    pub config: ConfigHint,
    /// Joint values written beside the pose (a CSV's `j1..jn`, degrees): the seed of the
    /// inverse kinematics, rewritten to the command's joints when those are solved.
    pub joints: Vec<Number>,
}

/// How a program writes an orientation.
#[derive(Clone, Copy, Debug)]
pub enum Orientation {
    /// KUKA A, B, C, degrees: `R = Rz(A)·Ry(B)·Rx(C)`.
    KukaAbcDeg([Number; 3]),
    /// A quaternion w, x, y, z (ABB's q1..q4).
    QuaternionWxyz([Number; 4]),
    /// A rotation vector, radians (Universal Robots' rx, ry, rz).
    RotationVectorRad([Number; 3]),
    /// Stäubli rx, ry, rz, degrees, about x, then the new y, then the new z:
    /// `R = Rx(rx)·Ry(ry)·Rz(rz)`.
    XyzIntrinsicDeg([Number; 3]),
}

/// What a program says about the configuration of the arm at a target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigHint {
    /// Nothing: the posture nearest the previous target's (or home) is taken.
    None,
    /// KUKA Status and Turn, as written (either may be missing).
    KukaStatusTurn {
        /// S: bit 0 overhead, bit 1 A3 ≥ φ (elbow up), bit 2 A5 ≤ 0.
        status: Option<u32>,
        /// T: bit i set when axis i + 1 is negative.
        turn: Option<u32>,
    },
    /// ABB robconf `[cf1, cf4, cf6, cfx]`: quadrants of axes 1, 4 and 6 and the
    /// configuration (bit 0 axis 5 negative, bit 1 backward, bit 2 behind).
    RapidConf([i64; 4]),
    /// This project's inverse-kinematics configuration (a CSV's `config`, as sample
    /// files write it): bit 0 shoulder back, bit 1 elbow down, bit 2 wrist flipped.
    Configuration(u8),
    /// Fanuc `CONFIG : 'N U T, 0, 0, 0'`: the configuration in this project's labels
    /// (`None` when the letters do not give all three), and three turn numbers (turn k:
    /// −180° + 360°k < J ≤ 180° + 360°k) of the joints the controller's turn axes name.
    FanucConfig {
        /// Bit 0 shoulder back (`B`), bit 1 elbow down (`D`), bit 2 wrist flipped (`F`).
        configuration: Option<u8>,
        /// The turn numbers, as written.
        turns: [Option<i8>; 3],
        /// The joints they are of: J4, J5, J6 unless the job says otherwise.
        turn_axes: TurnAxes,
    },
    /// Stäubli VAL3 `config` of a `pointRx`, each part as written; `None` where the
    /// controller chooses (`ssame`, `sfree`, `esame`, `efree`, `wsame`, `wfree`, or the
    /// attribute omitted, which is `same`).
    Val3 {
        /// `righty` (true): the wrist centre behind joint 1's axis (this project's
        /// shoulder back), or `lefty`.
        righty: Option<bool>,
        /// `epositive` (true): J3 ≥ 0 as the robot file counts it, or `enegative`.
        elbow_positive: Option<bool>,
        /// `wpositive` (true): J5 ≥ 0 as the robot file counts it, or `wnegative`.
        wrist_positive: Option<bool>,
    },
    /// Yaskawa `///RCONF l,m,n,o,p,q,…`: the manipulator type of the Cartesian positions
    /// after it.
    YaskawaRconf {
        /// `l`: 0 flip (the R axis, J4, within (−90°, 90°] turn for turn), 1 no flip.
        no_flip: bool,
        /// `m`: 0 upper arm, 1 lower arm (this project's elbow down).
        lower_arm: bool,
        /// `n`: 0 front, 1 rear (this project's shoulder back).
        rear: bool,
        /// `o`, `p`, `q`: the R (J4), T (J6) and S (J1) axis at 180° or more.
        at_least_180: [bool; 3],
    },
    /// A configuration the program writes but the reader cannot read or map (a value out
    /// of range, a field it does not know): the target is not corrected in a posture the
    /// program does not give.
    Unreadable {
        /// Where the value is written (bytes of the target's file).
        span: (usize, usize),
        /// What was expected there.
        expected: &'static str,
    },
}

/// A joint target's numbers.
#[derive(Clone, Debug)]
pub struct JointTarget {
    /// The joint values, first joint first (external axes are not included).
    pub joints: Vec<Number>,
    /// Their unit.
    pub unit: AngleUnit,
}

/// The frames one use of a target commands it in.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameUse {
    /// The TCP in the flange frame, when the program says (RAPID `tooldata`, URScript
    /// `set_tcp`); `None`: the job's tool.
    pub tool: Option<Isometry3<f64>>,
    /// The work object (base) in the robot's base frame, when the program says (RAPID
    /// `wobjdata`); `None`: the job's base.
    pub base: Option<Isometry3<f64>>,
    /// Where the use is written (the motion instruction), for messages.
    pub offset: usize,
    /// The use's place when another file holds it (a KRL `.dat`'s target moved to by its
    /// `.src`): `file:line:column`; `None`: `offset` in the target's own file.
    pub elsewhere: Option<String>,
    /// What the motion does with the target besides reaching it, said beside its
    /// correction: a KRL circle's end point when the circle's angle (`CA`) ends the motion
    /// elsewhere on the circle.
    pub note: Option<String>,
    /// The frames the use names but the program does not declare (RAPID `gun`, KRL
    /// `TOOL_DATA[1]` without `--krl-config`), which the job's `tool` or `base` option may
    /// then stand for (one name each).
    pub undeclared: Vec<Undeclared>,
    /// Frames the use depends on that no input can give (a `$BASE` computed at run time,
    /// a `set_tcp` of an expression, a stationary tool): the target is left unchanged,
    /// with this said.
    pub unknown: Vec<String>,
}

/// A frame a use names without the program giving its value.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Undeclared {
    /// A work object (base), or else a tool.
    pub base: bool,
    /// Its name as the program writes it (`gun`, `BASE_DATA[2]`).
    pub name: String,
}

impl Undeclared {
    /// `tool NAME` or `work object NAME`.
    pub fn describe(&self) -> String {
        format!(
            "{} {}",
            if self.base { "work object" } else { "tool" },
            self.name
        )
    }
}

/// A program read: its targets in the order they are written.
#[derive(Clone, Debug)]
pub struct Program {
    /// Its format.
    pub format: Format,
    /// Its targets.
    pub targets: Vec<ProgramTarget>,
    /// Where reading stopped, when the program holds more targets than the reader was
    /// allowed to read (the job sizes its work by them: crate docs): the byte offset.
    pub truncated_at: Option<usize>,
    /// Where its first motion instruction is written (any, those whose targets another file
    /// declares too): a program that moves must have targets to correct.
    pub first_motion: Option<usize>,
    /// The targets written in the program's partner file rather than in it (a KRL `.dat`
    /// read with its `.src`: the `.src`'s inline targets and refused motions, reported since
    /// this file's output does not hold them), by target index, ascending. Such a target's
    /// `offset` is the program's length (it is written nowhere in the program); its place
    /// is here, so that no target pays for a field only these few use.
    pub in_partner: Vec<PartnerPlace>,
}

/// Where a target written in the program's partner file is written there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartnerPlace {
    /// The target's index in [`Program::targets`].
    pub target: usize,
    /// 1-based line in the partner.
    pub line: usize,
    /// 1-based column in the partner, in bytes.
    pub column: usize,
}

impl Program {
    /// Where target `index` is written in the partner file, when it is written there.
    pub fn partner_place(&self, index: usize) -> Option<PartnerPlace> {
        let at = self
            .in_partner
            .binary_search_by_key(&index, |p| p.target)
            .ok()?;
        self.in_partner.get(at).copied()
    }
}

/// The joints the three turn numbers of a `CONFIG` belong to, as the controller's
/// `$SCR_GRP[1].$TURN_AXIS` defines them (`[1, 4, 6]` on an R-2000iB, `[4, 5, 6]` on many
/// LR Mates), and where they were taken from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TurnAxes {
    /// The joint of each turn number, 1 for J1; 0 for none (a controller may leave a
    /// place without a joint).
    pub joints: [u8; 3],
    /// Where the job took them from.
    pub from: TurnAxesFrom,
}

/// Where a job's turn axes come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TurnAxesFrom {
    /// Neither the options nor the frame file: J4, J5, J6.
    Default,
    /// `--fanuc-turn-axes`.
    Option,
    /// The frame file's `$SCR_GRP[1].$TURN_AXIS` (`--fanuc-frames`).
    Controller,
}

impl Default for TurnAxes {
    fn default() -> TurnAxes {
        TurnAxes {
            joints: [4, 5, 6],
            from: TurnAxesFrom::Default,
        }
    }
}

#[cfg(test)]
impl Program {
    /// Each target's name and the reason it is left unchanged (`None`: corrected), in
    /// reading order: what the readers' tests compare.
    pub(crate) fn reasons(&self) -> Vec<(&str, Option<Reason>)> {
        self.targets
            .iter()
            .map(|t| (t.name.as_str(), t.refused.as_ref().map(|r| r.reason)))
            .collect()
    }
}
