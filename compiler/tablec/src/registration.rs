//! Printing a registration of tracker-frame measurements (`--measured-in tracker`): the
//! transforms and the residuals they leave.

use adwi_identify::register::{translation_and_rotation_deg, Refined, Registration};
use adwi_runtime::kinematics::Transform;

/// Prints the registration: both transforms and the rigid fit's residuals.
pub fn print_registration(r: &Registration) {
    println!(
        "registration   {} rows in the tracker frame, {}, rigid fit of the nominal robot \
         ({} iterations)",
        r.rows,
        if r.orientation {
            "6-D (positions and orientations)"
        } else {
            "positions only (probe rotation kept from the robot file)"
        },
        r.iterations
    );
    print_fit("fit residuals", &r.fit());
}

/// Prints both transforms as an identification of the registered samples refined them
/// ([`Registration::refined`](adwi_identify::register::Registration::refined)), with the
/// identified model's residuals.
pub fn print_refined(refined: &Refined) {
    println!("refined        by the identification's base and tool parameters:");
    print_fit("residuals", refined);
}

/// Prints a validation set's own registration
/// ([`adwi_identify::measured::Registered::samples_registered_apart`]):
/// its tracker-to-base transform and the calibrated model's residuals.
pub fn print_validation_registration(r: &Registration) {
    println!(
        "validation     registered apart ({} rows): the robot's frame in the moved tracker's, \
         fitted to the calibrated model's TCP positions; the probe is the samples'",
        r.rows
    );
    print_fit("fit residuals", &r.fit());
}

/// Prints the registration of a series after the first (several series trained
/// together): its tracker-to-base transform, fitted to the robot identified from all of
/// them, and the probe they share.
pub fn print_series_registration(index: usize, r: &Registration) {
    println!(
        "series {index}       registered to the robot identified from every series ({} rows); \
         the probe is the first series'",
        r.rows
    );
    print_fit("fit residuals", &r.fit());
}

/// Both transforms, then the residuals they leave on a line of its own called `residuals`.
fn print_fit(residuals: &str, fit: &Refined) {
    print_transforms(&fit.base_in_tracker, &fit.probe);
    print_residuals(
        residuals,
        fit.position_rms_mm,
        fit.position_max_mm,
        fit.orientation_rms_rad.zip(fit.orientation_max_rad),
    );
}

fn print_transforms(base_in_tracker: &Transform, probe: &Transform) {
    for (name, t) in [
        ("base in tracker", base_in_tracker),
        ("probe on flange", probe),
    ] {
        let (p, r) = translation_and_rotation_deg(t);
        let angle = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        println!(
            "  {name}  translation ({:.4}, {:.4}, {:.4}) mm, rotation vector ({:.5}, {:.5}, \
             {:.5})° ({angle:.5}°)",
            p[0], p[1], p[2], r[0], r[1], r[2]
        );
    }
}

fn print_residuals(name: &str, rms_mm: f64, max_mm: f64, orientation: Option<(f64, f64)>) {
    let orientation = orientation.map_or(String::new(), |(rms, max)| {
        format!(
            "; orientation RMS {:.4} mrad, max {:.4} mrad",
            rms * 1e3,
            max * 1e3
        )
    });
    println!("  {name:<15}  position RMS {rms_mm:.4} mm, max {max_mm:.4} mm{orientation}");
}
