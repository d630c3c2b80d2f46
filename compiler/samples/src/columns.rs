//! Column names, their units, and the mapping from a file's own column names.

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;

use crate::pose::Convention;

/// Every column name the reader knows, as written in a file or on the left of a mapping.
pub const CANONICAL_COLUMNS: &[&str] = &[
    "x", "y", "z", "dx", "dy", "dz", "mx", "my", "mz", // positions
    "a", "b", "c", "q1", "q2", "q3", "q4", "qx", "qy", "qz", "qw", "w", "p", "r", "roll", "pitch",
    "yaw", "ex", "ey", "ez", // nominal orientations
    "ma", "mb", "mc", "mq1", "mq2", "mq3", "mq4", "mqx", "mqy", "mqz", "mqw", "mw", "mp", "mr",
    "mroll", "mpitch", "myaw", "mex", "mey", "mez", // measured orientations
    "rx", "ry", "rz", // orientation error
    "j1", "j2", "j3", "j4", "j5", "j6", "j7", "j8", "j9", "j10", "j11", "j12", // joints
    "config",
];

/// The most joint columns a file may have, `j1..j12`.
pub const MAX_JOINTS: usize = 12;

/// The joint columns, in order.
pub(crate) const JOINT_COLUMNS: [&str; MAX_JOINTS] = [
    "j1", "j2", "j3", "j4", "j5", "j6", "j7", "j8", "j9", "j10", "j11", "j12",
];

/// The columns of an orientation written in `convention`: the nominal (commanded) one, or
/// with `measured` the measured one (the same names with an `m` before them).
pub fn orientation_columns(convention: Convention, measured: bool) -> &'static [&'static str] {
    match (convention, measured) {
        (Convention::KukaAbc, false) => &["a", "b", "c"],
        (Convention::KukaAbc, true) => &["ma", "mb", "mc"],
        (Convention::QuaternionWxyz, false) => &["q1", "q2", "q3", "q4"],
        (Convention::QuaternionWxyz, true) => &["mq1", "mq2", "mq3", "mq4"],
        (Convention::QuaternionXyzw, false) => &["qx", "qy", "qz", "qw"],
        (Convention::QuaternionXyzw, true) => &["mqx", "mqy", "mqz", "mqw"],
        (Convention::FanucWpr, false) => &["w", "p", "r"],
        (Convention::FanucWpr, true) => &["mw", "mp", "mr"],
        (Convention::RollPitchYaw, false) => &["roll", "pitch", "yaw"],
        (Convention::RollPitchYaw, true) => &["mroll", "mpitch", "myaw"],
        (Convention::EulerXyz, false) => &["ex", "ey", "ez"],
        (Convention::EulerXyz, true) => &["mex", "mey", "mez"],
    }
}

/// A length unit: of position columns (nominal, error and measured positions), and of a
/// robot program's positions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LengthUnit {
    /// Millimetres, the unit of everything the reader returns (KRL, RAPID, CSV programs).
    #[default]
    Millimetre,
    /// Metres (URScript programs).
    Metre,
    /// Inches: G-code after `G20` (a mapping does not take them).
    Inch,
}

impl LengthUnit {
    /// Millimetres per unit.
    pub fn mm(self) -> f64 {
        match self {
            LengthUnit::Millimetre => 1.0,
            LengthUnit::Metre => 1000.0,
            LengthUnit::Inch => 25.4,
        }
    }

    /// The unit's symbol, as written in a mapping: `mm` or `m` (`in` for inches).
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Millimetre => "mm",
            LengthUnit::Metre => "m",
            LengthUnit::Inch => "in",
        }
    }

    /// The decimals that keep a length to 1e-4 mm, as a compensated program writes its
    /// positions: 4 in mm, 7 in m, 6 in inches.
    pub fn decimals(self) -> usize {
        match self {
            LengthUnit::Millimetre => 4,
            LengthUnit::Metre => 7,
            LengthUnit::Inch => 6,
        }
    }
}

/// An angle unit: of angle columns (joint angles, orientation angles, rotation vectors),
/// and of a robot program's joints (degrees in KRL, RAPID, CSV; radians in URScript).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AngleUnit {
    /// Degrees.
    #[default]
    Degree,
    /// Radians, the unit of everything the reader returns.
    Radian,
}

impl AngleUnit {
    /// Radians per unit.
    pub fn rad(self) -> f64 {
        match self {
            // The factor `f64::to_radians` multiplies by: a value in degrees converts to the
            // same bits either way.
            AngleUnit::Degree => std::f64::consts::PI / 180.0,
            AngleUnit::Radian => 1.0,
        }
    }

    /// The unit's symbol, as written in a mapping: `deg` or `rad`.
    pub fn symbol(self) -> &'static str {
        match self {
            AngleUnit::Degree => "deg",
            AngleUnit::Radian => "rad",
        }
    }

    /// The decimals that keep an angle to 1e-6°, as a compensated program writes its
    /// joints: 6 in degrees, 8 in radians.
    pub fn decimals(self) -> usize {
        match self {
            AngleUnit::Degree => 6,
            AngleUnit::Radian => 8,
        }
    }
}

/// A unit written after a column in a mapping (`x=Goal x:m`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    /// A length: positions, and prismatic joints.
    Length(LengthUnit),
    /// An angle: orientation angles, rotation vectors, and revolute joints.
    Angle(AngleUnit),
}

impl Unit {
    /// The unit's symbol: `mm`, `m`, `deg` or `rad`.
    pub fn symbol(self) -> &'static str {
        match self {
            Unit::Length(u) => u.symbol(),
            Unit::Angle(u) => u.symbol(),
        }
    }
}

impl fmt::Display for Unit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.symbol())
    }
}

/// A unit symbol that is not one of those a column takes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnitError {
    /// The symbol as written.
    pub found: String,
    /// The symbols allowed.
    pub allowed: &'static str,
}

impl fmt::Display for UnitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "unknown unit '{}': one of {}", self.found, self.allowed)
    }
}

impl std::error::Error for UnitError {}

impl FromStr for Unit {
    type Err = UnitError;

    fn from_str(s: &str) -> Result<Unit, UnitError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "mm" => Ok(Unit::Length(LengthUnit::Millimetre)),
            "m" => Ok(Unit::Length(LengthUnit::Metre)),
            "deg" => Ok(Unit::Angle(AngleUnit::Degree)),
            "rad" => Ok(Unit::Angle(AngleUnit::Radian)),
            _ => Err(UnitError {
                found: s.trim().to_string(),
                allowed: "mm, m, deg, rad",
            }),
        }
    }
}

impl FromStr for LengthUnit {
    type Err = UnitError;

    fn from_str(s: &str) -> Result<LengthUnit, UnitError> {
        match s.parse() {
            Ok(Unit::Length(u)) => Ok(u),
            _ => Err(UnitError {
                found: s.trim().to_string(),
                allowed: "mm, m",
            }),
        }
    }
}

impl FromStr for AngleUnit {
    type Err = UnitError;

    fn from_str(s: &str) -> Result<AngleUnit, UnitError> {
        match s.parse() {
            Ok(Unit::Angle(u)) => Ok(u),
            _ => Err(UnitError {
                found: s.trim().to_string(),
                allowed: "deg, rad",
            }),
        }
    }
}

/// What a column holds, which decides the units it takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Quantity {
    /// Positions: `mm` or `m`, default the file's length unit.
    Length,
    /// Orientation angles: `deg` or `rad`, default the file's angle unit.
    Angle,
    /// The rotation vector `rx,ry,rz`: `rad` unless its columns say `deg`.
    RotationVector,
    /// A joint: an angle (`deg`, `rad`; default the file's angle unit) or, for a prismatic
    /// joint, a length (`mm`, `m`).
    Joint,
    /// A quaternion component or the configuration: no unit.
    Unitless,
}

impl Quantity {
    /// What a canonical column holds; `None` for a name that is not one.
    pub(crate) fn of(canonical: &str) -> Option<Quantity> {
        Some(match canonical {
            "x" | "y" | "z" | "dx" | "dy" | "dz" | "mx" | "my" | "mz" => Quantity::Length,
            "rx" | "ry" | "rz" => Quantity::RotationVector,
            "config" => Quantity::Unitless,
            _ if JOINT_COLUMNS.contains(&canonical) => Quantity::Joint,
            _ => {
                let convention = Convention::ALL.into_iter().find(|&c| {
                    orientation_columns(c, false).contains(&canonical)
                        || orientation_columns(c, true).contains(&canonical)
                })?;
                if convention.is_quaternion() {
                    Quantity::Unitless
                } else {
                    Quantity::Angle
                }
            }
        })
    }

    /// Whether a column of this quantity can be written in `unit`.
    fn takes(self, unit: Unit) -> bool {
        matches!(
            (self, unit),
            (Quantity::Length, Unit::Length(_))
                | (Quantity::Angle | Quantity::RotationVector, Unit::Angle(_))
                | (Quantity::Joint, _)
        )
    }

    fn units(self) -> &'static str {
        match self {
            Quantity::Length => "mm or m",
            Quantity::Angle | Quantity::RotationVector => "deg or rad",
            Quantity::Joint => "deg or rad (mm or m for a prismatic joint)",
            Quantity::Unitless => "no unit",
        }
    }
}

/// Where a canonical column comes from: a source column, maybe negated, maybe with a unit.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Source {
    /// The source column's name, lower case.
    pub name: String,
    /// Whether the values are negated.
    pub negate: bool,
    /// The unit written in the mapping, if any.
    pub unit: Option<Unit>,
}

/// Which source column supplies each canonical column: negated or not, and in which unit.
///
/// Written `name=source[:unit],...`: a `-` before the source negates it, `:unit` (`mm`, `m`,
/// `deg`, `rad`) gives its unit; `name:unit` alone gives the unit of a column that is named
/// as the reader expects. Names are compared without case; a source name cannot hold `,`,
/// and a `:` in it must be followed by a unit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColumnMap {
    entries: HashMap<String, Source>,
}

/// What is wrong with a column mapping.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ColumnMapError {
    /// An item is neither `name=source` nor `name:unit`.
    NotAMapping(String),
    /// The name on the left is not a canonical column.
    UnknownName {
        /// The item as written.
        item: String,
        /// The name.
        name: String,
    },
    /// The item names no source column.
    NoSource(String),
    /// A canonical column is mapped twice.
    Twice(String),
    /// The unit is not a unit.
    UnknownUnit {
        /// The item as written.
        item: String,
        /// The unit as written.
        unit: String,
    },
    /// The unit does not fit the column (`x=foo:deg`).
    WrongUnit {
        /// The item as written.
        item: String,
        /// The canonical column.
        name: String,
        /// The units it takes.
        allowed: &'static str,
    },
}

/// The column names within a small edit of `name` (a typing error), closest first.
fn closest_columns(name: &str) -> Vec<&'static str> {
    let name = name.to_ascii_lowercase();
    let allowed = (name.chars().count() / 3).max(1);
    let close: Vec<(usize, &'static str)> = CANONICAL_COLUMNS
        .iter()
        .map(|c| (strsim::damerau_levenshtein(&name, c), *c))
        .filter(|(d, _)| *d <= allowed)
        .collect();
    let Some(best) = close.iter().map(|c| c.0).min() else {
        return Vec::new();
    };
    // Among the nearest, the names that share the most of the typed one's start (`xx` is
    // `x` doubled more likely than `dx` mistyped).
    let mut nearest: Vec<(f64, &'static str)> = close
        .into_iter()
        .filter(|(d, _)| *d == best)
        .map(|(_, c)| (strsim::jaro_winkler(&name, c), c))
        .collect();
    nearest.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(b.1)));
    let top = nearest.first().map_or(0.0, |c| c.0);
    nearest
        .into_iter()
        .take_while(|(similarity, _)| *similarity >= top - 0.05)
        .take(4)
        .map(|(_, c)| c)
        .collect()
}

impl fmt::Display for ColumnMapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ColumnMapError::NotAMapping(item) => write!(
                f,
                "column mapping '{item}' is not of the form name=column, name=column:unit or \
                 name:unit"
            ),
            ColumnMapError::UnknownName { item, name } => {
                write!(f, "column mapping '{item}': '{name}' is not a column name")?;
                match closest_columns(name).as_slice() {
                    [] => write!(
                        f,
                        " (x, y, z; dx, dy, dz or mx, my, mz; an orientation as a, b, c and \
                         its kin; j1..j12; config: docs/samples.md lists them all)"
                    ),
                    [one] => write!(f, ": did you mean '{one}'?"),
                    several => write!(f, ": did you mean one of {}?", several.join(", ")),
                }
            }
            ColumnMapError::NoSource(item) => {
                write!(f, "column mapping '{item}' names no source column")
            }
            ColumnMapError::Twice(name) => write!(f, "column mapping maps '{name}' twice"),
            ColumnMapError::UnknownUnit { item, unit } => write!(
                f,
                "column mapping '{item}': unknown unit '{unit}' (mm, m, deg or rad; a column \
                 name cannot hold ':')"
            ),
            ColumnMapError::WrongUnit {
                item,
                name,
                allowed,
            } => write!(f, "column mapping '{item}': '{name}' takes {allowed}"),
        }
    }
}

impl std::error::Error for ColumnMapError {}

impl ColumnMap {
    /// Parses `name=source[:unit],...` (see [`ColumnMap`]).
    ///
    /// # Errors
    ///
    /// An unknown canonical name, an item without `=` or unit, an empty source, a name
    /// mapped twice, an unknown unit or one the column does not take.
    pub fn parse(spec: &str) -> Result<ColumnMap, ColumnMapError> {
        let mut map = ColumnMap::default();
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (canonical, source) = match item.split_once('=') {
                Some(pair) => pair,
                // `x:m`: the column named as expected, in a unit.
                None => match item.split_once(':') {
                    Some((name, _)) => (name, item),
                    None => return Err(ColumnMapError::NotAMapping(item.to_string())),
                },
            };
            let canonical = canonical.trim().to_ascii_lowercase();
            let quantity = Quantity::of(&canonical).ok_or_else(|| ColumnMapError::UnknownName {
                item: item.to_string(),
                name: canonical.clone(),
            })?;
            let source = source.trim();
            let (negate, source) = match source.strip_prefix('-') {
                Some(s) => (true, s.trim()),
                None => (false, source),
            };
            let (source, unit) = match source.rsplit_once(':') {
                Some((name, unit)) => {
                    let unit: Unit = unit.parse().map_err(|_| ColumnMapError::UnknownUnit {
                        item: item.to_string(),
                        unit: unit.trim().to_string(),
                    })?;
                    if !quantity.takes(unit) {
                        return Err(ColumnMapError::WrongUnit {
                            item: item.to_string(),
                            name: canonical,
                            allowed: quantity.units(),
                        });
                    }
                    (name.trim(), Some(unit))
                }
                None => (source, None),
            };
            if source.is_empty() {
                return Err(ColumnMapError::NoSource(item.to_string()));
            }
            let entry = Source {
                name: source.to_ascii_lowercase(),
                negate,
                unit,
            };
            if map.entries.insert(canonical.clone(), entry).is_some() {
                return Err(ColumnMapError::Twice(canonical));
            }
        }
        Ok(map)
    }

    /// The source of a canonical column: as mapped; or the column of that name, unless a
    /// mapping takes that column for another (with `j1=q1,...`, the file's `q1` is a joint,
    /// not a quaternion component).
    pub(crate) fn find(&self, canonical: &str) -> Option<Source> {
        if let Some(source) = self.entries.get(canonical) {
            return Some(source.clone());
        }
        if self.entries.values().any(|s| s.name == canonical) {
            return None;
        }
        Some(self.source(canonical))
    }

    /// The mapped canonical columns and their sources, in [`CANONICAL_COLUMNS`] order.
    pub(crate) fn mapped(&self) -> impl Iterator<Item = (&'static str, &Source)> + '_ {
        CANONICAL_COLUMNS
            .iter()
            .filter_map(|&c| self.entries.get(c).map(|s| (c, s)))
    }

    /// Whether the mapping names `canonical`.
    pub(crate) fn maps(&self, canonical: &str) -> bool {
        self.entries.contains_key(canonical)
    }

    /// The source of a canonical column: as mapped, or the column of that name.
    pub(crate) fn source(&self, canonical: &str) -> Source {
        self.entries
            .get(canonical)
            .cloned()
            .unwrap_or_else(|| Source {
                name: canonical.to_string(),
                negate: false,
                unit: None,
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_canonical_column_has_a_quantity_and_every_group_is_canonical() {
        for name in CANONICAL_COLUMNS {
            assert!(Quantity::of(name).is_some(), "{name}");
        }
        for c in Convention::ALL {
            for measured in [false, true] {
                let names = orientation_columns(c, measured);
                assert_eq!(names.len(), c.value_count());
                assert!(
                    names.iter().all(|n| CANONICAL_COLUMNS.contains(n)),
                    "{names:?}"
                );
            }
        }
        assert!(JOINT_COLUMNS.iter().all(|n| CANONICAL_COLUMNS.contains(n)));
        let mut sorted = CANONICAL_COLUMNS.to_vec();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), CANONICAL_COLUMNS.len(), "a name listed twice");
    }

    #[test]
    fn mappings_take_units_negation_and_the_short_form() {
        let map =
            ColumnMap::parse("x=Goal x:m, dx=-x_dif:mm, ma=measurement_rx:DEG, y:m, j7=rail:m")
                .unwrap();
        let metre = Some(Unit::Length(LengthUnit::Metre));
        assert_eq!(
            map.source("x"),
            Source {
                name: "goal x".into(),
                negate: false,
                unit: metre
            }
        );
        assert!(map.source("dx").negate);
        assert_eq!(
            map.source("dx").unit,
            Some(Unit::Length(LengthUnit::Millimetre))
        );
        assert_eq!(map.source("ma").unit, Some(Unit::Angle(AngleUnit::Degree)));
        assert_eq!(map.source("y").name, "y");
        assert_eq!(map.source("y").unit, metre);
        assert_eq!(map.source("j7").unit, metre);
        assert_eq!(map.source("z").name, "z");
    }

    #[test]
    fn bad_mappings_are_refused_with_the_reason() {
        let err = |spec| ColumnMap::parse(spec).unwrap_err().to_string();
        assert!(err("q=x_t").contains("'q' is not a column name"));
        // A typing error is answered with the names it is closest to, not all of them.
        assert!(
            err("xx=x_t").contains("did you mean 'x'?"),
            "{}",
            err("xx=x_t")
        );
        assert!(err("dzz=e").contains("did you mean 'dz'?"));
        assert!(
            err("confg=e").contains("did you mean 'config'?"),
            "{}",
            err("confg=e")
        );
        assert!(!err("xx=x_t").contains("config"));
        assert!(err("tempreature=t").contains("docs/samples.md"));
        assert!(err("x=a,x=b").contains("maps 'x' twice"));
        assert!(err("x").contains("not of the form"));
        assert!(err("x=").contains("names no source"));
        assert!(err("x=:m").contains("names no source"));
        assert!(err("x=foo:furlong").contains("unknown unit 'furlong'"));
        assert!(err("x=foo:deg").contains("'x' takes mm or m"));
        assert!(err("a=foo:mm").contains("'a' takes deg or rad"));
        assert!(err("q1=foo:rad").contains("'q1' takes no unit"));
        assert!(err("config=foo:mm").contains("'config' takes no unit"));
        assert!(err("rx:m").contains("'rx' takes deg or rad"));
    }

    #[test]
    fn units_parse_from_their_symbols() {
        assert_eq!("m".parse::<LengthUnit>(), Ok(LengthUnit::Metre));
        assert_eq!(" MM ".parse::<LengthUnit>(), Ok(LengthUnit::Millimetre));
        assert_eq!("rad".parse::<AngleUnit>(), Ok(AngleUnit::Radian));
        assert!("deg".parse::<LengthUnit>().is_err());
        assert!("m".parse::<AngleUnit>().is_err());
        assert_eq!(AngleUnit::Degree.rad(), 1f64.to_radians());
    }
}
