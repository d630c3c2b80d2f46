//! Whether an identified parameter can be trusted, and the report of each parameter
//! (module docs of [`crate::calibrate`], "Trust").

use super::parameters::Parameter;
use super::solver::Fit;

/// Why a kept parameter was held at its nominal value (module docs, "Trust").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HoldReason {
    /// Its estimate lies beyond the plausible bound of its kind (for a compliance: the
    /// joint's whole compliance, the file's plus the estimate).
    Implausible {
        /// The estimate, mm, rad or µrad/(N·m).
        value: f64,
        /// The bound, mm, rad or µrad/(N·m).
        bound: f64,
    },
    /// A joint's whole compliance (the file's plus the estimate) is negative, and
    /// determined: the joint would stiffen under load, which no gear does.
    NegativeCompliance {
        /// The joint's whole compliance, µrad/(N·m).
        value: f64,
        /// The estimate's standard error, µrad/(N·m).
        standard_error: f64,
    },
    /// A joint-space term the likelihood does not support: adding it lowers the
    /// Bayesian information criterion less than its price, `z² = (value / SE)² < ln m`
    /// for `m` measured coordinates (module docs, "Joint-space terms").
    Unsupported {
        /// The estimate, rad.
        value: f64,
        /// Its standard error, rad.
        standard_error: f64,
        /// `sqrt(ln m)`: the `|value| / SE` a term must exceed.
        threshold: f64,
    },
    /// Its estimate is within a few standard errors of zero.
    Undetermined {
        /// The estimate, mm or rad.
        value: f64,
        /// Its standard error, mm or rad.
        standard_error: f64,
    },
}

impl HoldReason {
    /// The reason in words, values in mm, mrad or µrad/(N·m) as `parameter` takes them.
    pub fn describe(&self, parameter: Parameter) -> String {
        let show = |v: f64| {
            if parameter.is_compliance() {
                format!("{v:+.4} µrad/(N·m)")
            } else if parameter.is_length() {
                format!("{v:+.4} mm")
            } else {
                format!("{:+.4} mrad", v * 1e3)
            }
        };
        match *self {
            HoldReason::Implausible { value, bound } => format!(
                "implausible: estimate {} beyond ±{}",
                show(value),
                show(bound).trim_start_matches('+')
            ),
            HoldReason::Undetermined {
                value,
                standard_error,
            } => format!(
                "undetermined: estimate {} within {:.1} standard errors ({}) of zero",
                show(value),
                value.abs() / standard_error,
                show(standard_error).trim_start_matches('+')
            ),
            HoldReason::Unsupported {
                value,
                standard_error,
                threshold,
            } => format!(
                "not supported: estimate {} is {:.1} standard errors ({}) from zero, the \
                 information criterion (BIC) asks for {threshold:.1}",
                show(value),
                value.abs() / standard_error,
                show(standard_error).trim_start_matches('+')
            ),
            HoldReason::NegativeCompliance {
                value,
                standard_error,
            } => format!(
                "implausible: compliance {} is negative by {:.1} standard errors ({}): a joint \
                 does not stiffen under load",
                show(value),
                value.abs() / standard_error,
                show(standard_error).trim_start_matches('+')
            ),
        }
    }
}

/// What became of one parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParameterStatus {
    /// Identified: plausible and determined by the data.
    Identified,
    /// Kept by the pivoting but held at nominal: the estimate it had and why.
    Held {
        /// The estimate when it was held, mm or rad.
        estimate: f64,
        /// Why.
        reason: HoldReason,
    },
    /// Not separable from the identified parameters (pivoted QR), kept at nominal.
    Unidentifiable {
        /// Its independent fraction in the scaled Jacobian (0 for an exact redundancy).
        independent_fraction: f64,
        /// The identified parameter whose column is most like its own (largest |cosine|):
        /// for an exact redundancy of two, the one that took its place.
        most_like: Option<Parameter>,
    },
}

/// One parameter as a calibration engineer reads it: value, standard error, strongest
/// correlation, status and reason.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParameterReport {
    /// The parameter.
    pub parameter: Parameter,
    /// Its identified value (mm or rad), zero unless identified.
    pub value: f64,
    /// Its standard error (mm or rad): of the final fit when identified, of the fit that
    /// held it when held; `None` when unidentifiable.
    pub standard_error: Option<f64>,
    /// The parameter it correlates with most strongly, and the correlation, in the same fit.
    pub strongest_correlation: Option<(Parameter, f64)>,
    /// Identified, held or unidentifiable.
    pub status: ParameterStatus,
}

impl ParameterReport {
    /// `identified`, `held` or `unidentifiable`.
    pub fn status_name(&self) -> &'static str {
        match self.status {
            ParameterStatus::Identified => "identified",
            ParameterStatus::Held { .. } => "held",
            ParameterStatus::Unidentifiable { .. } => "unidentifiable",
        }
    }

    /// Why the parameter is not identified, in words; empty when it is.
    pub fn reason(&self) -> String {
        match self.status {
            ParameterStatus::Identified => String::new(),
            ParameterStatus::Held { reason, .. } => reason.describe(self.parameter),
            ParameterStatus::Unidentifiable {
                independent_fraction,
                most_like,
            } => match most_like {
                Some(p) => format!(
                    "redundant with the identified parameters, most like {p} (independent \
                     fraction {independent_fraction:.1e})"
                ),
                None => format!(
                    "not seen by these data (independent fraction {independent_fraction:.1e})"
                ),
            },
        }
    }
}

/// What the data say about one kept parameter.
pub(super) struct Assessment {
    pub(super) value: f64,
    pub(super) standard_error: f64,
    pub(super) correlation: Option<(Parameter, f64)>,
    /// Why it cannot be trusted, if it cannot.
    pub(super) reason: Option<HoldReason>,
    /// Which failing parameter to hold first: implausible ones (by how far beyond their
    /// bound), then undetermined ones (by standard error over value).
    pub(super) severity: f64,
}

impl Fit {
    /// The assessment of kept parameter `k` (module docs, "Trust"); `file_values` per
    /// column, added to the estimate where plausibility judges the whole value (a
    /// compliance).
    pub(super) fn assess(
        &self,
        parameters: &[Parameter],
        file_values: &[f64],
        k: usize,
        significance: f64,
        coordinates: usize,
    ) -> Assessment {
        let c = self.kept[k];
        let parameter = parameters[c];
        let value = self.x[c];
        let whole = file_values[c] + value;
        let variance = self.covariance[(k, k)];
        let standard_error = variance.max(0.0).sqrt();
        let correlation = (0..self.kept.len())
            .filter(|&l| l != k)
            .map(|l| {
                let denominator = (variance * self.covariance[(l, l)]).sqrt();
                let rho = if denominator > 0.0 {
                    self.covariance[(k, l)] / denominator
                } else {
                    0.0
                };
                (parameters[self.kept[l]], rho)
            })
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
        let bound = parameter.plausible_bound();
        // A joint-space term is kept for its evidence alone: a small standard error does
        // not make an estimate of noise a gear's (the criterion below judges it).
        let floor = if parameter.is_joint_term() {
            0.0
        } else {
            parameter.negligible_standard_error()
        };
        let determined = standard_error <= floor || value.abs() > significance * standard_error;
        let (reason, severity) = if whole.abs() > bound {
            (
                Some(HoldReason::Implausible {
                    value: whole,
                    bound,
                }),
                1e6 + whole.abs() / bound,
            )
        } else if parameter.is_compliance() && whole < 0.0 && determined {
            (
                Some(HoldReason::NegativeCompliance {
                    value: whole,
                    standard_error,
                }),
                1e6 + whole.abs() / standard_error.max(f64::MIN_POSITIVE),
            )
        } else if parameter.is_joint_term()
            && determined
            && value.abs() <= bic_threshold(coordinates) * standard_error
        {
            (
                Some(HoldReason::Unsupported {
                    value,
                    standard_error,
                    threshold: bic_threshold(coordinates),
                }),
                standard_error / value.abs().max(f64::MIN_POSITIVE),
            )
        } else if !determined {
            (
                Some(HoldReason::Undetermined {
                    value,
                    standard_error,
                }),
                standard_error / value.abs().max(f64::MIN_POSITIVE),
            )
        } else {
            (None, 0.0)
        };
        Assessment {
            value,
            standard_error,
            correlation,
            reason,
            severity,
        }
    }
}

/// The `|value| / SE` above which one more parameter lowers the Bayesian information
/// criterion of a least-squares fit of `coordinates` measured coordinates: `z² > ln m`
/// (the Wald statistic against the criterion's price of one parameter).
pub(super) fn bic_threshold(coordinates: usize) -> f64 {
    (coordinates.max(2) as f64).ln().sqrt()
}
