//! What an identification found, written once for every front end: the summary of a
//! calibration (the evaluation's splits, `tablec calibrate`, a hybrid build, the Python
//! package) and a row per parameter, every identified, held and unidentifiable term with
//! its value and standard error (joint-space terms and compliances among them). Its JSON
//! form is the evaluation's (`calibrations`), its text [`CalibrationSummary::text`] and
//! [`CalibrationSummary::parameter_table`].

use std::fmt::Write as _;

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
    /// Orientation RMS after identification, rad, as `tablec calibrate --json` and the
    /// Python package give it (the evaluation's JSON gives [`Self::orientation_rms_mrad`]).
    #[serde(skip)]
    pub orientation_rms_rad: Option<f64>,
    /// The residual standard deviation σ of one weighted measured coordinate, mm.
    #[serde(skip)]
    pub residual_sigma_mm: f64,
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
    /// Whether the parameter was identified (its value is the model's).
    pub fn is_identified(&self) -> bool {
        self.status == "identified"
    }

    /// The unit the tables show the value in, and the factor from [`Self::unit`] to it:
    /// angles in mrad, lengths in mm, compliances in µrad/(N·m).
    pub fn shown_unit(&self) -> (f64, &'static str) {
        if self.unit == "rad" {
            (1e3, "mrad")
        } else {
            (1.0, self.unit)
        }
    }

    /// The value as the tables show it: signed, to four decimals in [`Self::shown_unit`];
    /// `0` unless identified (a held or unidentifiable parameter stays at nominal).
    pub fn value_text(&self) -> String {
        if self.is_identified() {
            format!("{:+.4}", self.value * self.shown_unit().0)
        } else {
            "0".to_string()
        }
    }

    /// The standard error as the tables show it, to four decimals in
    /// [`Self::shown_unit`], `—` without one (unidentifiable).
    pub fn standard_error_text(&self) -> String {
        self.standard_error.map_or("—".to_string(), |s| {
            format!("{:.4}", s * self.shown_unit().0)
        })
    }

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
    /// The summary of `c`, identified on split `split` (0 for a validation set, a
    /// calibration or a build; the fold otherwise).
    pub fn new(split: usize, c: &Calibration) -> Self {
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
            orientation_rms_rad: c.orientation_rms_rad,
            residual_sigma_mm: c.residual_sigma_mm,
        }
    }

    /// The summary of a calibration made on all the samples given (`tablec calibrate`, a
    /// hybrid build).
    pub fn of(c: &Calibration) -> Self {
        Self::new(0, c)
    }

    /// How many parameters were identified, held at nominal and unidentifiable, as every
    /// summary opens.
    pub fn counts(&self) -> String {
        format!(
            "{} parameters identified, {} held at nominal, {} unidentifiable",
            self.identified.len(),
            self.held,
            self.unidentifiable.len()
        )
    }

    /// The summary as `tablec calibrate` and a hybrid `tablec build` print it: the counts,
    /// the residuals before and after (and, for a hybrid table, what its residual tier
    /// starts from, `table_residual_rms_mm`), then [`Self::parameter_table`].
    pub fn text(&self, table_residual_rms_mm: Option<f64>) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "calibration    {}, condition number {:.1}, {} iterations{}",
            self.counts(),
            self.condition_number,
            self.iterations,
            if self.converged {
                ""
            } else {
                " (not converged)"
            }
        );
        let table = table_residual_rms_mm
            .map_or(String::new(), |r| format!(" (table residuals {r:.4} mm)"));
        let _ = writeln!(
            out,
            "position RMS   {:.4} mm before, {:.4} mm after; residual σ {:.4} mm per \
             coordinate{table}",
            self.initial_position_rms_mm, self.position_rms_mm, self.residual_sigma_mm
        );
        if let Some(r) = self.orientation_rms_rad {
            let _ = writeln!(out, "orient. RMS    {:.4} mrad after", r * 1e3);
        }
        out.push_str(&self.parameter_table());
        out
    }

    /// The summary in one line, as the evaluation's text ends with one per
    /// identification (`of` of them: each fold's is numbered when there are several).
    pub fn line(&self, of: usize) -> String {
        format!(
            "kinematic identification{}: {}, condition number {:.1}, position RMS {:.4} → \
             {:.4} mm over the training samples, {} iterations{}",
            if of > 1 {
                format!(" (fold {})", self.split + 1)
            } else {
                String::new()
            },
            self.counts(),
            self.condition_number,
            self.initial_position_rms_mm,
            self.position_rms_mm,
            self.iterations,
            if self.converged {
                ""
            } else {
                " (NOT converged)"
            }
        )
    }

    /// The parameters as an aligned table: value, standard error (lengths in mm, angles
    /// in mrad, compliances in µrad/(N·m)), strongest correlation, status and, when not
    /// identified, why.
    pub fn parameter_table(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "  {:<11} {:>10} {:>9} {:<4} {:<20} {:<14} reason",
            "parameter", "value", "SE", "", "strongest corr.", "status"
        );
        for r in &self.parameters {
            let correlation = match (&r.correlated_with, r.correlation) {
                (Some(p), Some(rho)) => format!("{rho:+.2} {p}"),
                _ => "—".to_string(),
            };
            let _ = writeln!(
                out,
                "  {:<11} {:>10} {:>9} {:<4} {:<20} {:<14} {}",
                r.name,
                r.value_text(),
                r.standard_error_text(),
                r.shown_unit().1,
                correlation,
                r.status,
                r.reason
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(unit: &'static str, status: &'static str, value: f64) -> ParameterRow {
        ParameterRow {
            name: "p".to_string(),
            unit,
            value,
            held_estimate: None,
            standard_error: Some(0.5 * value.abs()),
            correlated_with: None,
            correlation: None,
            status,
            reason: String::new(),
        }
    }

    /// The terminal's table and the report show a row alike: angles in mrad, lengths in
    /// mm, a compliance in its own unit (the report once called it mm); a parameter not
    /// identified is 0 with its standard error kept.
    #[test]
    fn a_row_is_shown_in_its_unit_angles_in_mrad() {
        let angle = row("rad", "identified", -2e-4);
        assert_eq!(angle.shown_unit(), (1e3, "mrad"));
        assert_eq!(
            (angle.value_text(), angle.standard_error_text()),
            ("-0.2000".to_string(), "0.1000".to_string())
        );
        let compliance = row("µrad/(N·m)", "identified", 1.25);
        assert_eq!(compliance.shown_unit(), (1.0, "µrad/(N·m)"));
        assert_eq!(compliance.value_text(), "+1.2500");
        let held = row("mm", "held", 0.3);
        assert_eq!(
            (held.value_text(), held.standard_error_text()),
            ("0".to_string(), "0.1500".to_string())
        );
    }
}
