//! The ranges every number of a robot file, a URDF file and an error scenario must lie in,
//! checked where the number is read, with the file's field named.
//!
//! A value outside them is damage or a unit error, never a robot: it is refused before it
//! reaches any computation, so that no product of two of them overflows and no result of
//! simulation or identification can be infinite or NaN because of an input. The bounds are
//! wide — a factor of a thousand and more beyond any industrial robot — so that no real
//! file meets them:
//!
//! | quantity | range |
//! |---|---|
//! | lengths and positions: MD-H `a`, `d`, origins, tool, base, centres of mass, prismatic offsets and limits, tracker positions, deviations | within ±[`MAX_LENGTH_MM`] (1 km, the table format's bound, [`adwi_runtime::format::MAX_COORDINATE_MM`]) |
//! | angles of the geometry: twists, offsets, roll-pitch-yaw, KUKA A, B, C, their deviations, gear phases | within ±[`MAX_ANGLE_DEG`] |
//! | finite limits of a revolute joint | within ±[`MAX_JOINT_LIMIT_DEG`] (ten turns; infinite for a continuous joint) |
//! | masses (links, payload, URDF `<mass>`) | 0 to [`MAX_MASS_KG`] (the table format's, [`adwi_runtime::format::MAX_MASS_KG`]) |
//! | gravity compliance of a joint | within ±[`MAX_COMPLIANCE_URAD_PER_NM`] µrad/(N·m) |
//! | joint stiffness | at least [`MIN_STIFFNESS_NM_PER_RAD`] N·m/rad (the compliance bound inverted) |
//! | gear transmission error | amplitude within ±[`MAX_GEAR_AMPLITUDE_DEG`], at most [`MAX_GEAR_PERIODS_PER_REV`] periods per revolution |
//! | measurement noise σ | 0 to [`MAX_SIGMA_MM`] mm, 0 to [`MAX_SIGMA_MM`] mm per metre, 0 to [`MAX_ORIENTATION_SIGMA_RAD`] rad |
//! | URDF inertia tensor entries | within ±[`MAX_INERTIA_KG_M2`] kg·m² |
//! | URDF effort, velocity, damping, friction, acceleration, jerk limits | ≥ 0, infinite (no limit) only from URDF 1.2 on for effort, velocity and position limits |
//! | a robot's name | at most [`MAX_NAME_CHARS`] characters |
//!
//! Each bound holds to a relative 1e-9, so that a value at the bound that the tool writes
//! back after moving it between frames reads again.
//!
//! With every input inside them, a robot's positions stay within a few km and its gravity
//! torques within 10¹³ N·m, so that every deflection, pose and error computed from them is
//! finite; the outputs are checked finite all the same before they are returned.
//!
//! The checks ([`check`], [`check_all`], [`Quantity`]) are public so that the crates reading
//! the robot's other inputs (error scenarios in `adwi-simulate`, tracker registrations and
//! identification options in `adwi-identify`) hold them to these same ranges.

use adwi_runtime::format::Implausible;

use crate::error::RobotError;

/// The largest length or position, mm: 1 km, the table format's bound on coordinates.
pub const MAX_LENGTH_MM: f64 = adwi_runtime::format::MAX_COORDINATE_MM;
/// The largest angle of the geometry, degrees: any orientation is written within a turn;
/// two leave room for rounding (a URDF's `-6.2832`) and unusual conventions.
pub const MAX_ANGLE_DEG: f64 = 720.0;
/// The largest finite limit of a revolute joint, degrees: ten turns (a joint without
/// limits is continuous, its limits infinite).
pub const MAX_JOINT_LIMIT_DEG: f64 = 3600.0;
/// The largest mass of a link or payload, kg: the table format's bound.
pub const MAX_MASS_KG: f64 = adwi_runtime::format::MAX_MASS_KG;
/// The largest gravity compliance of a joint, µrad/(N·m): a stiffness of 100 N·m/rad, a
/// hundred times softer than the softest gear of a robot arm.
pub const MAX_COMPLIANCE_URAD_PER_NM: f64 = 1e4;
/// The smallest joint stiffness of a scenario, N·m/rad: [`MAX_COMPLIANCE_URAD_PER_NM`]
/// inverted.
pub const MIN_STIFFNESS_NM_PER_RAD: f64 = 1e6 / MAX_COMPLIANCE_URAD_PER_NM;
/// The largest amplitude of a gear's transmission error, degrees.
pub const MAX_GEAR_AMPLITUDE_DEG: f64 = 10.0;
/// The most periods per revolution of a gear's transmission error.
pub const MAX_GEAR_PERIODS_PER_REV: f64 = 1e4;
/// The largest position noise σ of a measurement, mm (and mm per metre of distance).
pub const MAX_SIGMA_MM: f64 = 1000.0;
/// The largest orientation noise σ of a measurement, rad.
pub const MAX_ORIENTATION_SIGMA_RAD: f64 = 1.0;
/// The largest magnitude of an inertia tensor entry, kg·m²: [`MAX_MASS_KG`] at 1 km.
pub const MAX_INERTIA_KG_M2: f64 = 1e12;

/// The most characters of a robot's name (robot files, URDF): messages quote it.
pub const MAX_NAME_CHARS: usize = 256;

/// Checks a robot's name from a file against [`MAX_NAME_CHARS`].
pub(crate) fn check_name(text: &str) -> Result<(), RobotError> {
    let count = text.chars().count();
    if count > MAX_NAME_CHARS {
        return Err(RobotError::Invalid {
            field: "name".into(),
            reason: format!(
                "'{}' has {count} characters, more than the {MAX_NAME_CHARS} a robot's name may have",
                name(text)
            ),
        });
    }
    Ok(())
}

/// The relative rounding a bound allows: 1e-9.
const ROUNDING: f64 = 1e-9;

/// What a number is, and so the range it must lie in (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// A length or position, mm.
    LengthMm,
    /// A length or position, m (URDF).
    LengthM,
    /// An angle of the geometry, degrees.
    AngleDeg,
    /// An angle of the geometry, rad.
    AngleRad,
    /// A finite revolute joint limit, degrees.
    JointLimitDeg,
    /// A finite revolute joint limit, rad.
    JointLimitRad,
    /// A revolute joint's value, degrees: within the joint limit bound.
    JointValueDeg,
    /// A mass, kg.
    MassKg,
    /// A gravity compliance, µrad/(N·m).
    ComplianceUradPerNm,
    /// A joint stiffness, N·m/rad.
    StiffnessNmPerRad,
    /// A gear error amplitude, degrees.
    GearAmplitudeDeg,
    /// Gear error periods per revolution.
    GearPeriodsPerRev,
    /// A position noise σ, mm or mm/m.
    SigmaMm,
    /// An orientation noise σ, rad.
    SigmaRad,
    /// An inertia tensor entry, kg·m².
    InertiaKgM2,
    /// A URDF dynamics value or limit (effort, velocity, damping, ...): ≥ 0, infinite
    /// allowed.
    NonNegative,
    /// Any finite number (URDF calibration references, mimic factors, soft limits).
    Finite,
}

impl Quantity {
    /// The bound `value` crosses, if any; `None` for a plausible value. NaN crosses every
    /// bound; an infinite value only the bounds of finite quantities.
    fn implausible(self, value: f64) -> Option<Implausible> {
        // A bound holds to rounding, so that a value at the bound written back by the tool
        // (a centre of mass moved between frames and back) reads again.
        let slack = |limit: f64| limit * (1.0 + ROUNDING);
        let within = |field: &'static str, limit: f64| {
            (value.abs() > slack(limit) || value.is_nan()).then_some(Implausible {
                field,
                value,
                rule: "within ±",
                limit,
            })
        };
        let between = |field: &'static str, lower: f64, upper: f64| {
            if value < lower - lower.abs() * ROUNDING || value.is_nan() {
                Some(Implausible {
                    field,
                    value,
                    rule: "at least ",
                    limit: lower,
                })
            } else if value > slack(upper) {
                Some(Implausible {
                    field,
                    value,
                    rule: "at most ",
                    limit: upper,
                })
            } else {
                None
            }
        };
        match self {
            Quantity::LengthMm => within("a length (mm)", MAX_LENGTH_MM),
            Quantity::LengthM => within("a length (m)", MAX_LENGTH_MM * 1e-3),
            Quantity::AngleDeg => within("an angle (deg)", MAX_ANGLE_DEG),
            Quantity::AngleRad => within("an angle (rad)", MAX_ANGLE_DEG.to_radians()),
            Quantity::JointLimitDeg => within("a joint limit (deg)", MAX_JOINT_LIMIT_DEG),
            Quantity::JointLimitRad => {
                within("a joint limit (rad)", MAX_JOINT_LIMIT_DEG.to_radians())
            }
            Quantity::JointValueDeg => within("a joint value (deg)", MAX_JOINT_LIMIT_DEG),
            Quantity::MassKg => between("a mass (kg)", 0.0, MAX_MASS_KG),
            Quantity::ComplianceUradPerNm => {
                within("a compliance (µrad/(N·m))", MAX_COMPLIANCE_URAD_PER_NM)
            }
            Quantity::StiffnessNmPerRad => {
                between("a stiffness (N·m/rad)", MIN_STIFFNESS_NM_PER_RAD, f64::MAX)
            }
            Quantity::GearAmplitudeDeg => {
                within("a gear error amplitude (deg)", MAX_GEAR_AMPLITUDE_DEG)
            }
            Quantity::GearPeriodsPerRev => within(
                "gear error periods per revolution",
                MAX_GEAR_PERIODS_PER_REV,
            ),
            Quantity::SigmaMm => between("a noise σ (mm)", 0.0, MAX_SIGMA_MM),
            Quantity::SigmaRad => between("a noise σ (rad)", 0.0, MAX_ORIENTATION_SIGMA_RAD),
            Quantity::InertiaKgM2 => within("an inertia (kg·m²)", MAX_INERTIA_KG_M2),
            Quantity::NonNegative => between("a limit or dynamics value", 0.0, f64::INFINITY),
            Quantity::Finite => within("a number", f64::MAX),
        }
    }

    /// Whether the quantity may be infinite (no limit).
    fn may_be_infinite(self) -> bool {
        self == Quantity::NonNegative
    }
}

/// Checks `value` as a `quantity`: [`RobotError::NonFinite`] for NaN or an infinity where
/// the quantity must be finite, [`RobotError::Implausible`] outside its range; `field`
/// names it as the file does (`joint 2 a_mm`).
pub fn check(
    value: f64,
    quantity: Quantity,
    field: impl FnOnce() -> String,
) -> Result<(), RobotError> {
    if value.is_nan() || (value.is_infinite() && !quantity.may_be_infinite()) {
        return Err(RobotError::NonFinite { field: field() });
    }
    match quantity.implausible(value) {
        None => Ok(()),
        Some(reason) => Err(RobotError::Implausible {
            field: field(),
            reason,
        }),
    }
}

/// [`check`] of every component of `values`, named `field[i]`.
pub fn check_all(
    values: &[f64],
    quantity: Quantity,
    field: impl Fn() -> String,
) -> Result<(), RobotError> {
    for (i, &v) in values.iter().enumerate() {
        check(v, quantity, || format!("{}[{i}]", field()))?;
    }
    Ok(())
}

/// A number as people read it: plain in the usual range, in exponent form outside it (the
/// plain form of 1e-300 has 300 zeros), as the runtime's messages write them; public so
/// that the messages about every input of a robot write numbers alike.
pub fn number(value: f64) -> String {
    if value == 0.0 || (1e-4..1e9).contains(&value.abs()) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

/// A name from a file as a message quotes it: at most 40 characters, then how many more
/// (a hostile file's names may be megabytes long).
pub(crate) fn name(text: &str) -> String {
    const SHOWN: usize = 40;
    let count = text.chars().count();
    if count <= SHOWN {
        text.to_owned()
    } else {
        let kept: String = text.chars().take(SHOWN).collect();
        format!("{kept}… ({} more characters)", count - SHOWN)
    }
}

/// The first `shown` of `names`, then "and N more": a list in a message stays short
/// whatever the file holds.
pub(crate) fn first_few<T: std::fmt::Display>(names: &[T], shown: usize) -> String {
    let listed: Vec<String> = names
        .iter()
        .take(shown)
        .map(|n| name(&n.to_string()))
        .collect();
    let listed = listed.join(", ");
    if names.len() > shown {
        format!("{listed} and {} more", names.len() - shown)
    } else {
        listed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_refuse_what_no_robot_has_and_name_the_field() {
        assert!(check(999_999.0, Quantity::LengthMm, String::new).is_ok());
        let error = check(-1e300, Quantity::LengthMm, || "joint 2 a_mm".into()).unwrap_err();
        assert_eq!(
            error.to_string(),
            "joint 2 a_mm: a length (mm) is -1e300, but must be within ±1000000"
        );
        let error = check(f64::NAN, Quantity::MassKg, || "payload mass_kg".into()).unwrap_err();
        assert_eq!(error.to_string(), "payload mass_kg is not a finite number");
        assert!(check(-5.0, Quantity::MassKg, String::new).is_err());
        assert!(check(f64::NEG_INFINITY, Quantity::MassKg, String::new).is_err());
        assert!(check(1e-308, Quantity::StiffnessNmPerRad, String::new).is_err());
        assert!(check(f64::INFINITY, Quantity::NonNegative, String::new).is_ok());
        assert!(check(-1.0, Quantity::NonNegative, String::new).is_err());
        assert!(check(1e308, Quantity::Finite, String::new).is_ok());
        let error = check_all(&[0.0, 1e7], Quantity::LengthMm, || {
            "tool translation_mm".into()
        })
        .unwrap_err();
        assert!(
            error.to_string().starts_with("tool translation_mm[1]: "),
            "{error}"
        );
    }

    #[test]
    fn long_lists_are_cut() {
        let names: Vec<String> = (0..2_000_000).map(|i| format!("l{i}")).collect();
        assert_eq!(first_few(&names, 3), "l0, l1, l2 and 1999997 more");
        assert_eq!(first_few(&names[..2], 3), "l0, l1");
    }
}
