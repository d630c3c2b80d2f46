//! What an identification found, as the reports show it: the summary of each split's
//! calibration and a row per parameter.

use adwi_identify::calibrate::{self, Calibration, Parameter};

/// What identification found, for reports.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CalibrationSummary {
    /// Which split it was identified on (0 for a validation set; the fold otherwise).
    pub split: usize,
    /// Identified parameters, in pivot order, with their values (mm or rad).
    pub identified: Vec<(String, f64)>,
    /// Unidentifiable parameters with their independent fraction.
    pub unidentifiable: Vec<(String, f64)>,
    /// Condition number of the identified parameters' scaled Jacobian.
    pub condition_number: f64,
    /// Position RMS over the training samples before identification, mm.
    pub initial_position_rms_mm: f64,
    /// Position RMS over the training samples after identification, mm.
    pub position_rms_mm: f64,
    /// Orientation RMS after identification, mrad, when measured.
    pub orientation_rms_mrad: Option<f64>,
    /// Levenberg–Marquardt iterations.
    pub iterations: u32,
    /// Whether it converged.
    pub converged: bool,
    /// How many parameters were held at nominal for want of trust.
    pub held: usize,
    /// Every parameter: value, standard error, strongest correlation, status and reason.
    pub parameters: Vec<ParameterRow>,
}

/// One parameter of an identification, for reports ([`calibrate::ParameterReport`]).
#[derive(Debug, Clone, serde::Serialize)]
pub struct ParameterRow {
    /// The parameter's name (`Δtheta6`, `tool z`).
    pub name: String,
    /// `mm`, `rad` or `µrad/(N·m)`.
    pub unit: &'static str,
    /// The identified value (0 unless identified), mm or rad.
    pub value: f64,
    /// The estimate it had when held at nominal, mm or rad.
    pub held_estimate: Option<f64>,
    /// Its standard error, mm or rad.
    pub standard_error: Option<f64>,
    /// The parameter it correlates with most strongly.
    pub correlated_with: Option<String>,
    /// That correlation, −1 to 1.
    pub correlation: Option<f64>,
    /// `identified`, `held` or `unidentifiable`.
    pub status: &'static str,
    /// Why not identified, in words; empty when identified.
    pub reason: String,
}

impl ParameterRow {
    /// The rows of a calibration, in column order.
    pub fn of(c: &Calibration) -> Vec<ParameterRow> {
        c.report
            .iter()
            .map(|r| ParameterRow {
                name: r.parameter.to_string(),
                unit: r.parameter.unit(),
                value: r.value,
                held_estimate: match r.status {
                    calibrate::ParameterStatus::Held { estimate, .. } => Some(estimate),
                    _ => None,
                },
                standard_error: r.standard_error,
                correlated_with: r.strongest_correlation.map(|(p, _)| p.to_string()),
                correlation: r.strongest_correlation.map(|(_, rho)| rho),
                status: r.status_name(),
                reason: r.reason(),
            })
            .collect()
    }
}

impl CalibrationSummary {
    pub(crate) fn new(split: usize, c: &Calibration) -> Self {
        let named = |p: Parameter| p.to_string();
        CalibrationSummary {
            split,
            identified: c
                .identified
                .iter()
                .map(|&p| (named(p), c.value(p)))
                .collect(),
            unidentifiable: c
                .unidentifiable
                .iter()
                .map(|&(p, ratio)| (named(p), ratio))
                .collect(),
            condition_number: c.condition_number,
            initial_position_rms_mm: c.initial_position_rms_mm,
            position_rms_mm: c.position_rms_mm,
            orientation_rms_mrad: c.orientation_rms_rad.map(|r| r * 1e3),
            iterations: c.iterations,
            converged: c.converged,
            held: c.held().len(),
            parameters: ParameterRow::of(c),
        }
    }
}
