//! Whether samples look like a robot's measured in millimetres.
//!
//! A file in metres read as millimetres parses without a single bad field: every
//! position is a thousand times too small, the samples span a millimetre, and everything
//! built from them is quietly wrong. Its warnings ([`SampleSet::plausibility_warnings`])
//! are typed and returned, for the caller to print; the library prints nothing.

use crate::SampleSet;

/// The smallest extent of sample positions a robot's workspace plausibly has, mm: samples
/// that vary at all span more than a centimetre (the largest side of their bounding box).
pub const MIN_PLAUSIBLE_EXTENT_MM: f64 = 10.0;
/// The largest extent of sample positions a robot's workspace plausibly has, mm: 100 m,
/// beyond the largest gantry.
pub const MAX_PLAUSIBLE_EXTENT_MM: f64 = 100_000.0;
/// The largest RMS of measured position errors a robot plausibly has, mm: uncalibrated
/// robots are off by a few millimetres, the largest and most loaded by a few tens.
pub const MAX_PLAUSIBLE_ERROR_RMS_MM: f64 = 100.0;

/// The largest orientation error a robot plausibly has, degrees: robots miss their
/// commanded orientation by hundredths to tenths of a degree (an uncalibrated UR5's flange
/// by up to 0.74°); 5° is an error in degrees read as radians (0.0873 read as rad), or
/// no orientation error at all. The reader refuses a sample beyond it.
pub const MAX_PLAUSIBLE_ROTATION_ERROR_DEG: f64 = 5.0;

/// The extents a robot's samples span, for guessing a unit: 5 cm to 50 m.
const ROBOT_EXTENT_MM: std::ops::RangeInclusive<f64> = 50.0..=50_000.0;

/// Units a length may have been written in, and millimetres per unit.
const UNITS: [(&str, f64); 4] = [("m", 1e3), ("cm", 10.0), ("in", 25.4), ("µm", 1e-3)];

/// Something about samples that looks wrong for a robot measured in millimetres, though
/// every field could be read.
#[derive(Debug, Clone, PartialEq)]
pub enum SampleWarning {
    /// The nominal positions span less than [`MIN_PLAUSIBLE_EXTENT_MM`] (but more than
    /// nothing) or more than [`MAX_PLAUSIBLE_EXTENT_MM`].
    Extent {
        /// The largest side of the nominal positions' bounding box, mm as read.
        extent_mm: f64,
        /// The RMS of the measured position errors' norms, mm as read.
        error_rms_mm: f64,
        /// The units that, read as millimetres, give these numbers for a robot's
        /// workspace of 5 cm to 50 m (`m`, `cm`, `in`, `µm`).
        likely_units: Vec<&'static str>,
    },
    /// The measured errors' RMS is more than [`MAX_PLAUSIBLE_ERROR_RMS_MM`]: not a robot's
    /// positioning error, but poses measured in another frame or unit.
    Errors {
        /// The RMS of the measured position errors' norms, mm as read.
        error_rms_mm: f64,
    },
}

impl std::fmt::Display for SampleWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SampleWarning::Extent {
                extent_mm,
                error_rms_mm,
                likely_units,
            } => {
                write!(
                    f,
                    "the samples span {} mm (the largest side of their bounding box), where a \
                     robot's workspace spans {} to {} mm",
                    number(*extent_mm),
                    number(MIN_PLAUSIBLE_EXTENT_MM),
                    number(MAX_PLAUSIBLE_EXTENT_MM)
                )?;
                match likely_units.as_slice() {
                    [] => Ok(()),
                    [unit] => {
                        let mm = UNITS
                            .iter()
                            .find(|(u, _)| u == unit)
                            .map_or(1.0, |(_, mm)| *mm);
                        write!(
                            f,
                            ": they look like {unit} read as mm (they would span {} mm, with \
                             an error RMS of {} mm instead of {} mm); read them with the \
                             length unit {unit}",
                            number(extent_mm * mm),
                            number(error_rms_mm * mm),
                            number(*error_rms_mm)
                        )
                    }
                    several => write!(
                        f,
                        ": they may be in {} read as mm; read them with their length unit",
                        several.join(", ")
                    ),
                }
            }
            SampleWarning::Errors { error_rms_mm } => write!(
                f,
                "the measured errors have an RMS of {} mm, more than the {} mm of any robot's \
                 positioning error: are the measured poses in another frame (a tracker's) or \
                 another unit?",
                number(*error_rms_mm),
                number(MAX_PLAUSIBLE_ERROR_RMS_MM)
            ),
        }
    }
}

impl SampleSet {
    /// What about these samples looks wrong for a robot measured in millimetres (module
    /// docs): an extent or an error size no robot has, with the unit the numbers seem to
    /// be in. Empty for plausible samples, and for samples at a single position.
    pub fn plausibility_warnings(&self) -> Vec<SampleWarning> {
        let mut out = Vec::new();
        if self.is_empty() {
            return out;
        }
        let error_rms_mm = (self
            .error_mm
            .iter()
            .map(|e| e.iter().map(|v| v * v).sum::<f64>())
            .sum::<f64>()
            / self.len() as f64)
            .sqrt();
        let bounds = adwi_runtime::format::bounding_box(self.nominal_mm.iter().copied());
        if let Some((lo, hi)) = bounds {
            let extent_mm = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
            let implausible = extent_mm > 0.0
                && !(MIN_PLAUSIBLE_EXTENT_MM..=MAX_PLAUSIBLE_EXTENT_MM).contains(&extent_mm);
            if implausible {
                let likely_units = UNITS
                    .iter()
                    .filter(|(_, mm)| ROBOT_EXTENT_MM.contains(&(extent_mm * mm)))
                    .map(|(unit, _)| *unit)
                    .collect();
                out.push(SampleWarning::Extent {
                    extent_mm,
                    error_rms_mm,
                    likely_units,
                });
            }
        }
        if error_rms_mm > MAX_PLAUSIBLE_ERROR_RMS_MM {
            out.push(SampleWarning::Errors { error_rms_mm });
        }
        out
    }
}

/// A number as people read it: four significant digits, plain in the usual range, in
/// exponent form outside it.
pub(crate) fn number(value: f64) -> String {
    let value: f64 = format!("{value:.3e}").parse().unwrap_or(value);
    if value == 0.0 || (1e-4..1e9).contains(&value.abs()) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ColumnMap;

    /// A lattice of `side` mm with errors of `error` mm, every number times `scale`.
    fn lattice(side: f64, error: f64, scale: f64) -> SampleSet {
        let mut set = SampleSet::default();
        for i in 0..4 {
            for j in 0..4 {
                let p = [i as f64 * side / 3.0, j as f64 * side / 3.0, 1000.0];
                set.nominal_mm.push(p.map(|v| v * scale));
                set.error_mm.push([error * scale, 0.0, 0.0]);
                set.lines.push(2 + 4 * i + j);
            }
        }
        set
    }

    #[test]
    fn metres_read_as_millimetres_are_flagged_with_the_unit() {
        assert!(lattice(600.0, 2.7, 1.0).plausibility_warnings().is_empty());
        let warnings = lattice(600.0, 2.7, 1e-3).plausibility_warnings();
        let [SampleWarning::Extent {
            extent_mm,
            error_rms_mm,
            likely_units,
        }] = &warnings[..]
        else {
            panic!("{warnings:?}")
        };
        assert!((extent_mm - 0.6).abs() < 1e-12 && (error_rms_mm - 0.0027).abs() < 1e-12);
        assert_eq!(likely_units, &["m"]);
        assert_eq!(
            warnings[0].to_string(),
            "the samples span 0.6 mm (the largest side of their bounding box), where a robot's \
             workspace spans 10 to 100000 mm: they look like m read as mm (they would span 600 \
             mm, with an error RMS of 2.7 mm instead of 0.0027 mm); read them with the length \
             unit m"
        );
        // Micrometres: too large, errors too.
        let warnings = lattice(600.0, 2.7, 1e3).plausibility_warnings();
        assert!(
            matches!(&warnings[..], [SampleWarning::Extent { likely_units, .. }, SampleWarning::Errors { .. }] if likely_units == &["µm"]),
            "{warnings:?}"
        );
        // Ambiguous: 5 mm may be metres, centimetres or inches.
        let warnings = lattice(5.0, 0.01, 1.0).plausibility_warnings();
        assert!(
            warnings[0]
                .to_string()
                .ends_with("they may be in m, cm, in read as mm; read them with their length unit"),
            "{}",
            warnings[0]
        );
        // One position only (repeatability): nothing to say.
        assert!(lattice(0.0, 0.01, 1.0).plausibility_warnings().is_empty());
        // Errors of a tracker frame read as the base's.
        let warnings = lattice(600.0, 2500.0, 1.0).plausibility_warnings();
        assert_eq!(
            warnings,
            [SampleWarning::Errors {
                error_rms_mm: 2500.0
            }]
        );
    }

    /// The UR5's laser-tracker grid (mm) is plausible; the same numbers in metres read as
    /// millimetres are flagged, with the unit.
    #[test]
    fn the_ur5_grid_in_metres_is_flagged() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tables/ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv");
        let map = ColumnMap::parse("x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif").unwrap();
        let mut samples = crate::read_samples(&path, &map).unwrap();
        assert!(samples.plausibility_warnings().is_empty());
        for (p, e) in samples.nominal_mm.iter_mut().zip(&mut samples.error_mm) {
            *p = p.map(|v| v * 1e-3);
            *e = e.map(|v| v * 1e-3);
        }
        let warnings = samples.plausibility_warnings();
        let [SampleWarning::Extent { likely_units, .. }] = &warnings[..] else {
            panic!("{warnings:?}")
        };
        assert_eq!(likely_units, &["m"]);
        println!("{}", warnings[0]);
    }
}
