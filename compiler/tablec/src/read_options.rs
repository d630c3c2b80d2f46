//! The reading options shared by `tablec build`, `tablec eval` and `tablec query --targets`:
//! one definition, so that every command reads a file the same way from the same flags.

use adwi_samples::{AngleUnit, ColumnMap, Decimal, Delimiter, LengthUnit};

/// How sample and target files are read: column names, separators, units.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ReadOptions {
    /// Column mapping for files named otherwise, comma-separated `NAME=SOURCE[:UNIT]`
    /// items: the file's column SOURCE supplies the column NAME (x, dx, a, j1, ...; see the
    /// README); `-` before SOURCE negates it; `:UNIT` (mm, m, deg, rad) gives its unit, and
    /// `NAME:UNIT` alone the unit of a column already named NAME. The columns of one group
    /// (x,y,z; ma,mb,mc; ...) take one unit. Example:
    /// `x=Goal x:m,y=Goal y:m,z=Goal z:m,dx=-x_dif,ma=measurement_rx:deg,j1:rad`.
    #[arg(long, value_name = "MAP")]
    pub columns: Option<String>,
    /// Field separator: comma, semicolon or tab [default: the one the header line uses
    /// most].
    #[arg(long, value_name = "SEP")]
    pub delimiter: Option<Delimiter>,
    /// Decimal mark: point or comma [default: point in comma-separated files, otherwise
    /// that of the first number with one].
    #[arg(long, value_name = "MARK")]
    pub decimal: Option<Decimal>,
    /// Unit of position columns (x,y,z, dx,dy,dz, mx,my,mz) the mapping gives none: mm or
    /// m [default: mm].
    #[arg(long, value_name = "UNIT")]
    pub length_unit: Option<LengthUnit>,
    /// Unit of joint and orientation-angle columns the mapping gives none: deg or rad
    /// [default: deg]. The rotation vector rx,ry,rz is in rad unless mapped `:deg`.
    #[arg(long, value_name = "UNIT")]
    pub angle_unit: Option<AngleUnit>,
}

impl ReadOptions {
    /// The column mapping and the reader's options.
    ///
    /// # Errors
    ///
    /// A malformed `--columns`.
    pub fn resolve(&self) -> anyhow::Result<(ColumnMap, adwi_samples::ReadOptions)> {
        let columns = ColumnMap::parse(self.columns.as_deref().unwrap_or(""))?;
        let options = adwi_samples::ReadOptions {
            delimiter: self.delimiter,
            decimal: self.decimal,
            length_unit: self.length_unit.unwrap_or_default(),
            angle_unit: self.angle_unit.unwrap_or_default(),
        };
        Ok((columns, options))
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
