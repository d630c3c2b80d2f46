//! `tablec calibrate`: the calibration job ([`adwi_jobs::CalibrateJob`]), its parameters
//! printed with their standard errors.

use adwi_identify::calibrate::Calibration;
use adwi_jobs::{CalibrateArgs, CalibrateJob};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: CalibrateArgs,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let calibrated = CalibrateJob::new(args.job)?.run()?;
    if let Some((registration, refined)) = &calibrated.registration {
        crate::registration::print_registration(registration);
        crate::registration::print_refined(refined);
    }
    for (i, r) in calibrated.series_registrations.iter().enumerate() {
        crate::registration::print_series_registration(i + 2, r);
    }
    print_identification(&calibrated.calibration, None);
    if let Some(t) = &calibrated.truth {
        print_truth(t);
    }
    for path in &calibrated.written {
        println!("wrote          {}", path.display());
    }
    crate::warn(&calibrated.warnings);
    Ok(())
}

/// What identification found, as `build` (hybrid) and `calibrate` report it: how many
/// parameters were identified, held at nominal for want of trust, or unidentifiable; the
/// residuals before and after (and, for a hybrid table, what its residual tier starts
/// from); then every parameter's value, standard error, strongest correlation, status and
/// reason.
pub fn print_identification(c: &Calibration, table_residual_rms_mm: Option<f64>) {
    println!(
        "calibration    {} parameters identified, {} held at nominal, {} unidentifiable, condition number {:.1}, {} iterations{}",
        c.identified.len(),
        c.held().len(),
        c.unidentifiable.len(),
        c.condition_number,
        c.iterations,
        if c.converged { "" } else { " (not converged)" }
    );
    let table =
        table_residual_rms_mm.map_or(String::new(), |r| format!(" (table residuals {r:.4} mm)"));
    println!(
        "position RMS   {:.4} mm before, {:.4} mm after; residual σ {:.4} mm per coordinate{table}",
        c.initial_position_rms_mm, c.position_rms_mm, c.residual_sigma_mm
    );
    if let Some(r) = c.orientation_rms_rad {
        println!("orient. RMS    {:.4} mrad after", r * 1e3);
    }
    print!(
        "{}",
        adwi_eval::output::parameter_table(&adwi_eval::ParameterRow::of(c))
    );
}

/// The identification against the simulated robot's truth: the parameter error (lengths
/// and angles apart) and the position error over the workspace poses.
fn print_truth(t: &adwi_measure::truth::TruthComparison) {
    let rms =
        |v: Option<f64>, unit: &str| v.map_or("—".to_string(), |v| format!("{v:.4} {unit}"));
    let lengths = t
        .parameters
        .iter()
        .filter(|p| p.parameter.is_length())
        .count();
    println!(
        "truth params   identified − true RMS {} ({lengths} lengths), {} ({} angles); {} of them not identified here (counted at 0), {} identified here only (not compared)",
        rms(t.length_rms_mm, "mm"),
        rms(t.angle_rms_mrad, "mrad"),
        t.parameters.len() - lengths,
        t.missed,
        t.not_compared
    );
    println!(
        "truth position |model − true robot| over {} poses: mean {:.4} mm, RMS {:.4} mm, max {:.4} mm",
        t.poses, t.position_mean_mm, t.position_rms_mm, t.position_max_mm
    );
}
