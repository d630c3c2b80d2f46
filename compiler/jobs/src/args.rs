//! The options several jobs share, each defined once: how sample files are read
//! ([`Reading`]), the table's method and grid ([`TableArgs`]), the robot ([`RobotArgs`]) and
//! the frame measurements are in ([`Frame`]).
//!
//! Every options struct is both a clap argument group (what `tablec` parses) and a serde
//! struct (what the Python package's keyword arguments deserialize into), with the same
//! names and the same defaults: an option is added in one place. The `Default` of each
//! struct is what clap gives when no flag is passed (tested).
// The field docs are clap's help text, where the paper's [λ] and [ζ] read as written.
#![allow(rustdoc::broken_intra_doc_links)]

use std::path::PathBuf;

use adwi_compile::build::BuildOptions;
use adwi_compile::posture::Posture;
use adwi_runtime::format::ServedField;
use adwi_runtime::method::MethodParams;
use adwi_samples::{AngleUnit, ColumnMap, Decimal, Delimiter, LengthUnit};
use serde::Deserialize;

use crate::JobError;

/// The paper's parameters, the defaults of the method's options.
const PAPER: MethodParams<()> = MethodParams::paper(());

/// How sample, validation and target files are read: column names, separators, units.
#[derive(clap::Args, Deserialize, Debug, Clone, Default, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Reading {
    /// Column mapping for files named otherwise, comma-separated `NAME=SOURCE[:UNIT]`
    /// items: the file's column SOURCE supplies the column NAME (x, dx, a, j1, ...; see
    /// docs/samples.md); `-` before SOURCE negates it; `:UNIT` (mm, m, deg, rad) gives its
    /// unit, and `NAME:UNIT` alone the unit of a column already named NAME. The columns of
    /// one group (x,y,z; ma,mb,mc; ...) take one unit. Example:
    /// `x=Goal x:m,y=Goal y:m,z=Goal z:m,dx=-x_dif,ma=measurement_rx:deg,j1:rad`.
    #[arg(long, value_name = "MAP")]
    pub columns: Option<String>,
    /// Field separator: comma, semicolon or tab [default: the one the header line uses
    /// most].
    #[arg(long, value_name = "SEP")]
    #[serde(deserialize_with = "parsed::option")]
    pub delimiter: Option<Delimiter>,
    /// Decimal mark: point or comma [default: point in comma-separated files, otherwise
    /// that of the first number with one].
    #[arg(long, value_name = "MARK")]
    #[serde(deserialize_with = "parsed::option")]
    pub decimal: Option<Decimal>,
    /// Unit of position columns (x,y,z, dx,dy,dz, mx,my,mz) the mapping gives none: mm or
    /// m [default: mm].
    #[arg(long, value_name = "UNIT")]
    #[serde(deserialize_with = "parsed::option")]
    pub length_unit: Option<LengthUnit>,
    /// Unit of joint and orientation-angle columns the mapping gives none: deg or rad
    /// [default: deg]. The rotation vector rx,ry,rz is in rad unless mapped `:deg`.
    #[arg(long, value_name = "UNIT")]
    #[serde(deserialize_with = "parsed::option")]
    pub angle_unit: Option<AngleUnit>,
}

impl Reading {
    /// The column mapping and the reader's options.
    ///
    /// # Errors
    ///
    /// A malformed column mapping.
    pub fn resolve(&self) -> Result<(ColumnMap, adwi_samples::ReadOptions), JobError> {
        let columns = ColumnMap::parse(self.columns.as_deref().unwrap_or(""))
            .map_err(|e| JobError::option("columns", e))?;
        let options = adwi_samples::ReadOptions {
            delimiter: self.delimiter,
            decimal: self.decimal,
            length_unit: self.length_unit.unwrap_or_default(),
            angle_unit: self.angle_unit.unwrap_or_default(),
            prismatic_joints: 0,
        };
        Ok((columns, options))
    }

    /// [`Reading::resolve`] for a file of `robot`'s samples or poses: its prismatic joints'
    /// columns are lengths where the mapping gives no unit (mm by default), as `tablec
    /// simulate` and `tablec plan` write them.
    ///
    /// # Errors
    ///
    /// As [`Reading::resolve`].
    pub fn resolve_for(
        &self,
        robot: Option<&adwi_robot::Robot>,
    ) -> Result<(ColumnMap, adwi_samples::ReadOptions), JobError> {
        let (columns, mut options) = self.resolve()?;
        options.prismatic_joints = robot.map_or(0, adwi_robot::Robot::prismatic_joints);
        Ok((columns, options))
    }

    /// Whether any option was given (a command that reads no file refuses them).
    pub fn is_given(&self) -> bool {
        *self != Reading::default()
    }

    /// The ids of these options' arguments, for a command that takes them only together
    /// with another argument.
    pub const IDS: [&'static str; 5] = [
        "columns",
        "delimiter",
        "decimal",
        "length_unit",
        "angle_unit",
    ];
}

/// A box's minimum and maximum corners, mm, base frame.
pub type Bounds = ([f64; 3], [f64; 3]);

/// What a table's served field holds, as asked for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ServedFieldChoice {
    /// Chosen by the build's own evidence (cross-validation on the training samples).
    #[default]
    Auto,
    /// This one.
    Given(ServedField),
}

impl ServedFieldChoice {
    /// The field given; `None` for `auto`.
    pub fn fixed(self) -> Option<ServedField> {
        match self {
            ServedFieldChoice::Auto => None,
            ServedFieldChoice::Given(field) => Some(field),
        }
    }
}

impl std::str::FromStr for ServedFieldChoice {
    type Err = String;

    fn from_str(text: &str) -> Result<ServedFieldChoice, String> {
        if text == "auto" {
            return Ok(ServedFieldChoice::Auto);
        }
        ServedField::from_name(text)
            .map(ServedFieldChoice::Given)
            .ok_or_else(|| {
                format!("'{text}': choose auto, method or kriging (kriging-tool-axis: the older name of kriging)")
            })
    }
}

impl std::fmt::Display for ServedFieldChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ServedFieldChoice::Auto => f.write_str("auto"),
            ServedFieldChoice::Given(field) => f.write_str(field.name()),
        }
    }
}

/// Whether a hybrid table gets a posture term ([`adwi_compile::posture`]), as asked for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PostureChoice {
    /// Added when the build's cross-validation on the training samples says it helps by
    /// the documented margin ([`crate::choice::POSTURE_MIN_GAIN_FRACTION`],
    /// [`crate::choice::POSTURE_MIN_GAIN_MM`]); never for a position-only table.
    #[default]
    Auto,
    /// Always added (a hybrid table).
    On,
    /// Never added.
    Off,
}

impl std::str::FromStr for PostureChoice {
    type Err = String;

    fn from_str(text: &str) -> Result<PostureChoice, String> {
        match text {
            "auto" => Ok(PostureChoice::Auto),
            "on" => Ok(PostureChoice::On),
            "off" => Ok(PostureChoice::Off),
            _ => Err(format!("'{text}': choose auto, on or off")),
        }
    }
}

impl std::fmt::Display for PostureChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PostureChoice::Auto => "auto",
            PostureChoice::On => "on",
            PostureChoice::Off => "off",
        })
    }
}

/// How much of a hybrid table's residual field the table holds, as asked for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ResidualWeightChoice {
    /// A weight in [0, 1] learned from held-out data: each series predicted from the
    /// others when several are given, else each spatial block of the samples from the
    /// others ([`crate::choice::CrossValidation::residual_weight`]).
    #[default]
    Auto,
    /// The whole field.
    Full,
}

impl std::str::FromStr for ResidualWeightChoice {
    type Err = String;

    fn from_str(text: &str) -> Result<ResidualWeightChoice, String> {
        match text {
            "auto" => Ok(ResidualWeightChoice::Auto),
            "full" => Ok(ResidualWeightChoice::Full),
            _ => Err(format!("'{text}': choose auto or full")),
        }
    }
}

impl std::fmt::Display for ResidualWeightChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ResidualWeightChoice::Auto => "auto",
            ResidualWeightChoice::Full => "full",
        })
    }
}

/// The method's parameters and the grid of a table.
#[derive(clap::Args, Deserialize, Debug, Clone, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct TableArgs {
    /// Cell edge length, mm [default: sample spacing / 2].
    #[arg(long, value_name = "MM")]
    pub cell: Option<f64>,
    /// Neighbourhood radius ε, mm [default: 2 × sample spacing].
    #[arg(long, value_name = "MM")]
    pub radius: Option<f64>,
    /// At most this many neighbours [default: 8].
    #[arg(long)]
    pub k: Option<u32>,
    /// ω1, the weight of λ [default: 0.87, or 1 − w2].
    #[arg(long)]
    pub w1: Option<f64>,
    /// ω2, the weight of ζ [default: 0.13, or 1 − w1].
    #[arg(long)]
    pub w2: Option<f64>,
    /// r, the power on λ and ζ (0 to 2).
    #[arg(long, default_value_t = PAPER.power)]
    pub power: f64,
    /// [λ], the admissibility threshold on λ, 1/mm.
    #[arg(long, default_value_t = PAPER.lambda_min_per_mm)]
    pub lambda_min: f64,
    /// [ζ], the admissibility threshold on ζ, 1/mm².
    #[arg(long, default_value_t = PAPER.zeta_min_per_mm2)]
    pub zeta_min: f64,
    /// Skip the consistency screen (40) on neighbour errors.
    #[arg(long)]
    pub no_consistency_screen: bool,
    /// Grid box, mm: xmin,ymin,zmin,xmax,ymax,zmax [default: samples' box grown by ε].
    #[arg(
        long,
        value_name = "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX",
        allow_hyphen_values = true,
        value_parser = parse_bounds
    )]
    #[serde(deserialize_with = "bounds")]
    pub bounds: Option<Bounds>,
    /// Joint-space screen, degrees: when a query gives the target's joint angles, a sample
    /// is admissible only if each of its joint angles is within this of the target's
    /// (needs samples with j1..jn) [default: off].
    #[arg(long, value_name = "DEG")]
    pub joint_radius: Option<f64>,
    /// What the served field's nodes hold: `auto` chooses by cross-validation on the
    /// samples alone (a hybrid table's held out by series, or by spatial blocks of one
    /// series); `method`, the method's own answer (what the exact tier answers,
    /// tabulated); `kriging`, kriging with a nugget of the samples' errors (a hybrid
    /// table's residuals) in Cartesian distance, which smooths their measurement noise; on
    /// a hybrid table with a part that turns with the nominal tool's approach axis at the
    /// query's joint values, where the samples' likelihood gives that part weight
    /// (`kriging-tool-axis` is its older name). The exact tier answers the method either
    /// way.
    #[arg(long, value_name = "FIELD", default_value_t = ServedFieldChoice::Auto)]
    #[serde(deserialize_with = "parsed::value")]
    pub served_field: ServedFieldChoice,
    /// A hybrid table's posture term, what the residual owes to the arm's posture and not
    /// to the position alone (joint elasticity, gear errors of a redundant arm's elbow):
    /// `auto` adds it when cross-validation on the samples alone says it helps (`eval`:
    /// on each split's training samples alone); `on`, always; `off`, never.
    #[arg(long, value_name = "WHEN", default_value_t = PostureChoice::Auto)]
    #[serde(deserialize_with = "parsed::value")]
    pub posture: PostureChoice,
    /// A hybrid table's residual field weight: `auto`, a weight in [0, 1] learned from
    /// held-out data (each series predicted from the others when several are given, else
    /// each of 5 spatial blocks of the samples from the others): a field that does not
    /// carry to poses elsewhere is faded toward the model alone; `full`, the whole field.
    #[arg(long, value_name = "WEIGHT", default_value_t = ResidualWeightChoice::Auto)]
    #[serde(deserialize_with = "parsed::value")]
    pub residual_weight: ResidualWeightChoice,
    /// Samples averaged within voxels of this edge, mm, before the table is built; 0
    /// keeps every sample [default: with a derived cell, none when the table fits
    /// --max-table-mb, else the finest voxel of 1/64 to 1/4 of the sample spacing that
    /// fits it].
    #[arg(long, value_name = "MM")]
    pub merge_voxel: Option<f64>,
    /// The most the table may take, MB (10⁶ bytes), with a derived cell: samples too many
    /// are merged within it, and a build that cannot keep it is refused before any work
    /// [default: 64, merging where that helps, else the table takes what its samples need].
    #[arg(long, value_name = "MB")]
    pub max_table_mb: Option<f64>,
}

impl Default for TableArgs {
    fn default() -> TableArgs {
        TableArgs {
            cell: None,
            radius: None,
            k: None,
            w1: None,
            w2: None,
            power: PAPER.power,
            lambda_min: PAPER.lambda_min_per_mm,
            zeta_min: PAPER.zeta_min_per_mm2,
            no_consistency_screen: false,
            bounds: None,
            joint_radius: None,
            served_field: ServedFieldChoice::Auto,
            posture: PostureChoice::Auto,
            residual_weight: ResidualWeightChoice::Auto,
            merge_voxel: None,
            max_table_mb: None,
        }
    }
}

impl TableArgs {
    /// The compiler's options with `served_field`: the one given
    /// ([`ServedFieldChoice::fixed`]), or the one chosen for `auto`.
    pub fn build_options(&self, served_field: ServedField) -> BuildOptions {
        let (w1, w2) = adwi_compile::build::resolve_weights(self.w1, self.w2);
        BuildOptions {
            method: MethodParams {
                radius_mm: self.radius,
                max_neighbours: self.k.unwrap_or(PAPER.max_neighbours),
                w1,
                w2,
                power: self.power,
                lambda_min_per_mm: self.lambda_min,
                zeta_min_per_mm2: self.zeta_min,
                consistency_screen: !self.no_consistency_screen,
            },
            cell_mm: self.cell,
            bounds_mm: self.bounds,
            joint_radius_deg: self.joint_radius,
            tuning: None,
            kriging_choices: None,
            served_field,
            posture: match self.posture {
                PostureChoice::On => Posture::Fit,
                PostureChoice::Auto | PostureChoice::Off => Posture::Off,
            },
            merge_voxel_mm: self.merge_voxel,
            // Not finite or not positive: 0, which the build refuses.
            max_table_bytes: self.max_table_mb.map(|mb| {
                if mb.is_finite() && mb > 0.0 {
                    (mb * 1e6) as u128
                } else {
                    0
                }
            }),
        }
    }
}

/// `xmin,ymin,zmin,xmax,ymax,zmax` in one argument (`-500,-500,0,500,500,900`).
fn parse_bounds(text: &str) -> Result<Bounds, String> {
    bounds_of(&parse_number_list(text)?)
}

fn bounds_of(values: &[f64]) -> Result<Bounds, String> {
    match *values {
        [x0, y0, z0, x1, y1, z1] => Ok(([x0, y0, z0], [x1, y1, z1])),
        _ => Err(format!(
            "six numbers are needed, xmin,ymin,zmin,xmax,ymax,zmax; {} given",
            values.len()
        )),
    }
}

/// Bounds from a list of six numbers (Python's `bounds=[...]`).
fn bounds<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<Bounds>, D::Error> {
    let values: Option<Vec<f64>> = Option::deserialize(d)?;
    values
        .map(|v| bounds_of(&v).map_err(serde::de::Error::custom))
        .transpose()
}

/// The largest angle a command takes, degrees: three turns each way
/// ([`adwi_measure::MAX_ANGLE_DEG`]).
pub const MAX_ANGLE_DEG: f64 = adwi_measure::MAX_ANGLE_DEG;

/// The largest coordinate a command takes, mm: a table's own bound
/// ([`adwi_runtime::format::MAX_COORDINATE_MM`], a kilometre).
pub const MAX_COORDINATE_MM: f64 = adwi_runtime::format::MAX_COORDINATE_MM;

/// Refuses a position coordinate beyond [`MAX_COORDINATE_MM`], naming `what`.
///
/// # Errors
///
/// The value and the bound, in words.
pub fn check_coordinate_mm(what: &str, value: f64) -> Result<(), String> {
    if value.abs() <= MAX_COORDINATE_MM {
        return Ok(());
    }
    Err(format!(
        "{what} {} mm is more than {MAX_COORDINATE_MM:e} mm from the base; give \
         millimetres in the robot's base frame",
        short(value)
    ))
}

/// Refuses an angle beyond [`MAX_ANGLE_DEG`], naming `what`.
///
/// # Errors
///
/// The value and the bound, in words.
pub fn check_angle_deg(what: &str, value: f64) -> Result<(), String> {
    if value.abs() <= MAX_ANGLE_DEG {
        return Ok(());
    }
    Err(format!(
        "{what} {}° is more than three turns ({MAX_ANGLE_DEG}°); give degrees",
        short(value)
    ))
}

/// A number as a message shows it: as written up to a billion, in exponent form beyond
/// (1e308 printed in full is 309 digits).
fn short(value: f64) -> String {
    if value.abs() < 1e9 {
        value.to_string()
    } else {
        format!("{value:e}")
    }
}

/// A frame `X,Y,Z,A,B,C` (mm, KUKA degrees), each value finite and in range
/// ([`check_coordinate_mm`], [`check_angle_deg`]), such as `--tool 0,0,180,0,0,0`.
///
/// # Errors
///
/// Not six finite numbers, or one out of range.
pub fn parse_frame(text: &str) -> Result<[f64; 6], String> {
    let values: [f64; 6] = parse_number_list(text)?
        .try_into()
        .map_err(|v: Vec<f64>| format!("a frame is six numbers X,Y,Z,A,B,C, not {}", v.len()))?;
    for (name, v) in ["X", "Y", "Z"].iter().zip(&values[..3]) {
        check_coordinate_mm(name, *v)?;
    }
    for (name, v) in ["A", "B", "C"].iter().zip(&values[3..]) {
        check_angle_deg(name, *v)?;
    }
    Ok(values)
}

/// Parses a comma-separated list of finite numbers, such as `--joints -22.9,1.5,...`.
///
/// # Errors
///
/// An item that is not a finite number, named.
pub fn parse_number_list(text: &str) -> Result<Vec<f64>, String> {
    text.split(',')
        .map(|item| {
            let item = item.trim();
            match item.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                Ok(_) => Err(format!("'{item}' is not a finite number")),
                Err(_) => Err(format!("'{item}' is not a number")),
            }
        })
        .collect()
}

/// Three comma-separated finite numbers, such as `--min 1350,50,850`.
///
/// # Errors
///
/// Not three finite numbers.
pub fn parse_triple(text: &str) -> Result<[f64; 3], String> {
    let values = parse_number_list(text)?;
    values.try_into().map_err(|v: Vec<f64>| {
        format!(
            "three comma-separated numbers are needed, {} given",
            v.len()
        )
    })
}

/// The robot file, and for a URDF the links its chain runs between.
#[derive(clap::Args, Deserialize, Debug, Clone, Default, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct RobotArgs {
    /// The robot file (TOML, or URDF by its .urdf extension; e.g. tables/ur5/robot.toml).
    #[arg(long, value_name = "ROBOT")]
    pub robot: Option<PathBuf>,
    /// URDF robots: the link the chain starts at, the robot's base frame [default: the
    /// file's only root link].
    #[arg(long, value_name = "LINK")]
    pub base_link: Option<String>,
    /// URDF robots: the link the chain ends at, the TCP's frame [default: the only leaf
    /// link below the base].
    #[arg(long, value_name = "LINK")]
    pub tip_link: Option<String>,
    /// URDF robots: the flange, the link tool data (--tool, a program's) are given in,
    /// fixed to the last movable joint's link [default: tool0, else flange, where the file has it so,
    /// else the last movable joint's link].
    #[arg(long, value_name = "LINK")]
    pub flange_link: Option<String>,
}

impl RobotArgs {
    /// The links of a URDF chain.
    pub fn links(&self) -> adwi_robot::LinkNames {
        adwi_robot::LinkNames {
            base_link: self.base_link.clone(),
            tip_link: self.tip_link.clone(),
            flange_link: self.flange_link.clone(),
        }
    }

    /// Refuses link names without a robot file to apply them to.
    pub(crate) fn check(&self) -> Result<(), JobError> {
        let links = [&self.base_link, &self.tip_link, &self.flange_link];
        if self.robot.is_none() && links.iter().any(|l| l.is_some()) {
            return Err(JobError::Options(
                "--base-link, --tip-link and --flange-link name the links of a URDF robot: \
                 give the robot file (--robot)"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// The frame measured poses are in.
#[derive(clap::ValueEnum, Deserialize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Frame {
    /// The robot's base frame: the file holds errors, or measured poses in the base frame.
    #[default]
    Base,
    /// A laser tracker's own frame: the file holds joints j1..jn and measured positions
    /// mx,my,mz (and, from a 6-D probe, a measured orientation), registered to the robot
    /// first.
    Tracker,
}

/// Deserializing through `FromStr`, for the options whose text the command line parses
/// the same way.
pub(crate) mod parsed {
    use serde::Deserialize;
    use std::fmt::Display;
    use std::str::FromStr;

    pub fn value<'de, D, T>(d: D) -> Result<T, D::Error>
    where
        D: serde::Deserializer<'de>,
        T: FromStr<Err: Display>,
    {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }

    pub fn option<'de, D, T>(d: D) -> Result<Option<T>, D::Error>
    where
        D: serde::Deserializer<'de>,
        T: FromStr<Err: Display>,
    {
        let text: Option<String> = Option::deserialize(d)?;
        text.map(|t| t.parse().map_err(serde::de::Error::custom))
            .transpose()
    }

    pub fn list<'de, D, T>(d: D) -> Result<Option<Vec<T>>, D::Error>
    where
        D: serde::Deserializer<'de>,
        T: FromStr<Err: Display>,
    {
        let items: Option<Vec<String>> = Option::deserialize(d)?;
        items
            .map(|items| {
                items
                    .iter()
                    .map(|t| t.parse().map_err(serde::de::Error::custom))
                    .collect()
            })
            .transpose()
    }
}
