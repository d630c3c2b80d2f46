//! The evaluation's figures as a terminal table, CSV and JSON.
//!
//! All three carry the same rows: `uncompensated` (the measured errors themselves), then one
//! row per method with its residuals after compensation. Figures are residual norms:
//! mean, RMS, 95th percentile (nearest rank) and maximum, position in mm and orientation
//! in mrad.

use std::fmt::Write as _;

use crate::baselines::ResidualStats;

use super::{Evaluation, MethodResult};

/// One row of the figures: a label, counts and statistics.
struct Row<'a> {
    label: &'a str,
    predicted: usize,
    not_predicted: usize,
    position: Option<&'a ResidualStats>,
    orientation: Option<&'a ResidualStats>,
    note: String,
}

fn rows(e: &Evaluation) -> Vec<Row<'_>> {
    let mut rows = vec![Row {
        label: "uncompensated",
        predicted: e.nominal_mm.len(),
        not_predicted: 0,
        position: Some(&e.uncompensated_position_mm),
        orientation: e.uncompensated_orientation_mrad.as_ref(),
        note: String::new(),
    }];
    rows.extend(e.methods.iter().map(|m| Row {
        label: m.method.name(),
        predicted: m.predicted(),
        not_predicted: m.not_predicted_count(),
        position: m.position_mm.as_ref(),
        orientation: m.orientation_mrad.as_ref(),
        note: m.note(),
    }));
    rows
}

fn figures(s: Option<&ResidualStats>) -> [Option<f64>; 4] {
    match s {
        Some(s) => [s.mean_norm, s.rms_norm, s.p95_norm, s.max_norm].map(Some),
        None => [None; 4],
    }
}

/// How well the points know a position mean: its standard error, mm, and the p value of
/// the residuals' shared offset.
fn resolution(s: Option<&ResidualStats>) -> [Option<f64>; 2] {
    s.map_or([None; 2], |s| {
        [s.mean_norm_standard_error, s.mean_per_axis_p_value]
    })
}

/// The figures as an aligned text table for the terminal, with notes on missing points
/// and unsupported methods below it.
pub fn terminal_table(e: &Evaluation) -> String {
    let orientation = e.uncompensated_orientation_mrad.is_some();
    let rows = rows(e);
    // The label column fits the longest method name.
    let w = rows
        .iter()
        .map(|r| r.label.chars().count())
        .max()
        .unwrap_or(0)
        .max(16);
    let mut out = String::new();
    let _ = writeln!(out, "{}", e.protocol);
    let _ = write!(
        out,
        "{:<w$} {:>6} {:>6} │ {:>9} {:>9} {:>9} {:>9}",
        "", "points", "", "position", "residual", "norm", "mm"
    );
    if orientation {
        let _ = write!(
            out,
            " │ {:>8} {:>8} {:>8} {:>8}",
            "orient.", "residual", "norm", "mrad"
        );
    }
    out.push('\n');
    let _ = write!(
        out,
        "{:<w$} {:>6} {:>6} │ {:>9} {:>9} {:>9} {:>9}",
        "method", "pred.", "missed", "mean", "rms", "p95", "max"
    );
    if orientation {
        let _ = write!(
            out,
            " │ {:>8} {:>8} {:>8} {:>8}",
            "mean", "rms", "p95", "max"
        );
    }
    out.push('\n');
    let cell = |v: Option<f64>, width: usize, decimals: usize| match v {
        Some(v) => format!("{v:>width$.decimals$}"),
        None => format!("{:>width$}", "—"),
    };
    let mut notes = Vec::new();
    for row in rows {
        let _ = write!(
            out,
            "{:<w$} {:>6} {:>6} │",
            row.label, row.predicted, row.not_predicted
        );
        for v in figures(row.position) {
            let _ = write!(out, " {}", cell(v, 9, 4));
        }
        if orientation {
            let _ = write!(out, " │");
            for v in figures(row.orientation) {
                let _ = write!(out, " {}", cell(v, 8, 4));
            }
        }
        out.push('\n');
        if !row.note.is_empty() {
            notes.push(format!("{}: {}", row.label, row.note));
        }
    }
    if let Some(floor) = &e.noise_floor {
        let _ = write!(out, "{:<w$} {:>6} {:>6} │", "noise floor", "", "");
        let _ = writeln!(
            out,
            " {} {:>9} {:>9} {:>9}",
            cell(floor.best_mean_mm, 9, 4),
            "",
            "",
            ""
        );
        notes.push(noise_floor_note(floor));
    }
    if let Some(c) = &e.comparison {
        notes.extend(comparison_notes(e, c));
    }
    notes.extend(harmonics_note(&e.harmonics_choices));
    notes.extend(split_choice_notes(e));
    for (method, reason) in &e.skipped {
        notes.push(format!("{method}: not run: {reason}"));
    }
    for note in notes {
        let _ = writeln!(out, "  {note}");
    }
    for c in &e.calibrations {
        let _ = writeln!(out, "  {}", c.line(e.calibrations.len()));
    }
    if let Some(c) = e.calibrations.first() {
        if e.calibrations.len() > 1 {
            let _ = writeln!(out, "  parameters identified in fold 1:");
        }
        out.push_str(&c.parameter_table());
    }
    out
}

/// The identification's harmonic count chosen on each split's training samples
/// (`--harmonics auto`): the count, and with one split the counts' held-out means and how
/// they were held out; `None` when no count was chosen.
fn harmonics_note(choices: &[crate::SplitHarmonics]) -> Option<String> {
    let first = choices.first()?;
    if let [only] = choices {
        let c = &only.choice;
        let means: Vec<String> = (c.candidates.iter())
            .map(|k| {
                let mean = k.cv_mean_mm.map_or("—".to_string(), |m| format!("{m:.4}"));
                format!("{}: {mean}", k.harmonics)
            })
            .collect();
        let reach = match &c.series_reach {
            Some(r) if !r.judges() => format!(
                "; not by the series held out, {} of whose {} poses lie within the joint \
                 angles the other series span",
                r.within_range, r.held_out_poses
            ),
            Some(r) => format!(
                "; at the {} of {} held-out poses within the joint angles the other series span",
                r.within_range, r.held_out_poses
            ),
            None => String::new(),
        };
        return Some(format!(
            "harmonic count chosen on the training samples by {}, the model alone{reach}: {} \
             (held-out mean mm by count: {})",
            c.held_out.describe(c.folds),
            c.chosen,
            means.join(", ")
        ));
    }
    let mut counts: Vec<u8> = choices.iter().map(|h| h.choice.chosen).collect();
    counts.sort_unstable();
    counts.dedup();
    let tally: Vec<String> = (counts.iter())
        .map(|&n| {
            let splits = choices.iter().filter(|h| h.choice.chosen == n).count();
            format!("{n} in {splits} of {}", choices.len())
        })
        .collect();
    Some(format!(
        "harmonic count chosen on each split's training samples by {}, the model alone: {} \
         splits",
        first.choice.held_out.describe(first.choice.folds),
        tally.join(", ")
    ))
}

/// The noise floor in words: the nuggets, the total variance and the mean they imply.
/// Per served-tier method whose table was chosen per split: the served field of each
/// split and, for a hybrid table, in which splits the posture term was turned on, with
/// the cross-validated means it was decided on.
fn split_choice_notes(e: &Evaluation) -> Vec<String> {
    let mut notes = Vec::new();
    let splits = e
        .split_choices
        .iter()
        .map(|c| c.split + 1)
        .max()
        .unwrap_or(0);
    // "fold 2 " before each split's choice in k-fold, nothing with one split.
    let name = |split: usize| {
        if splits > 1 {
            format!("fold {} ", split + 1)
        } else {
            String::new()
        }
    };
    for method in e.methods.iter().map(|m| m.method) {
        let choices: Vec<_> = e
            .split_choices
            .iter()
            .filter(|c| c.method == method)
            .collect();
        if choices.is_empty() {
            continue;
        }
        let fields: Vec<String> = choices
            .iter()
            .map(|c| format!("{}{}", name(c.split), c.served_field))
            .collect();
        notes.push(format!(
            "{method}: served field {}{}",
            if splits > 1 { "per split: " } else { "" },
            fields.join(", ")
        ));
        let weights: Vec<String> = choices
            .iter()
            .filter_map(|c| {
                c.residual_weight.map(|w| {
                    format!(
                        "{}{:.3} (held-out mean {:.4} mm; model alone {:.4}, whole field {:.4})",
                        name(c.split),
                        w.weight,
                        w.weighted_mm,
                        w.model_mm,
                        w.full_mm
                    )
                })
            })
            .collect();
        if !weights.is_empty() {
            notes.push(format!(
                "{method}: residual weight learned from {} training samples' held-out series \
                 or regions: {}",
                if splits > 1 { "each split's" } else { "the" },
                weights.join(", ")
            ));
        }
        let decided: Vec<_> = choices
            .iter()
            .filter_map(|c| c.posture.map(|p| (c.split, p)))
            .collect();
        if decided.is_empty() {
            continue;
        }
        let on = decided.iter().filter(|(_, p)| p.on).count();
        let mm = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.4}"));
        let each: Vec<String> = decided
            .iter()
            .map(|(split, p)| {
                format!(
                    "{}{} ({} → {} mm)",
                    name(*split),
                    if p.on { "on" } else { "off" },
                    mm(p.without_mm),
                    mm(p.with_mm)
                )
            })
            .collect();
        notes.push(if splits > 1 {
            format!(
                "{method}: posture term decided on each split's training samples (their \
                 cross-validated mean without → with it): on in {on} of {}: {}",
                decided.len(),
                each.join(", ")
            )
        } else {
            format!(
                "{method}: posture term decided on the training samples (their \
                 cross-validated mean without → with it): {}",
                each.join(", ")
            )
        });
    }
    notes
}

fn noise_floor_note(floor: &crate::noise_floor::NoiseFloor) -> String {
    let nugget =
        |n: Option<f64>, e: Option<&crate::noise_floor::NuggetEstimate>, unit: &str| match (n, e) {
            (Some(n), Some(e)) => format!(
                "{n:.5} mm² ({} bins to {:.1} {unit}, spacing {:.1} {unit})",
                e.bins.len(),
                e.bins.last().map_or(0.0, |b| b.lag),
                e.spacing
            ),
            _ => "—".to_string(),
        };
    format!(
        "noise floor: nugget of the {} of the {} training samples {} in Cartesian \
         distance, {} in joint distance; total variance {:.5} mm²; a perfect predictor \
         would leave {} mm mean (Gaussian, per-axis σ² = smaller nugget / 3)",
        floor.basis,
        floor.samples,
        nugget(floor.nugget_mm2_cartesian, floor.cartesian.as_ref(), "mm"),
        nugget(floor.nugget_mm2_joint, floor.joint.as_ref(), "°"),
        floor.total_variance_mm2,
        floor
            .best_mean_mm
            .map_or("—".to_string(), |m| format!("{m:.4}")),
    )
}

/// What the points resolve, in words: the best method's mean with its standard error, the
/// others' paired differences from it, and the residual offsets unlikely to be chance.
fn comparison_notes(e: &Evaluation, c: &crate::comparison::Comparison) -> Vec<String> {
    let Some(reference) = e.method(c.reference) else {
        return Vec::new();
    };
    let Some(stats) = reference.position_mm.as_ref() else {
        return Vec::new();
    };
    let points = e.nominal_mm.len();
    let differences: Vec<String> = c
        .against
        .iter()
        .map(|d| {
            let over = if d.points == points {
                String::new()
            } else {
                format!(" (over {} points)", d.points)
            };
            format!(
                "{} {:+.4}{}{over}",
                d.method.name(),
                d.mean_difference_mm,
                plus_minus(d.standard_error_mm)
            )
        })
        .collect();
    let mut notes = vec![if differences.is_empty() {
        // One method alone: what it leaves, against what the robot did without it.
        let u = &e.uncompensated_position_mm;
        let before = if u.mean_norm > 0.0 {
            let removed = 100.0 * (1.0 - stats.mean_norm / u.mean_norm);
            format!(
                "; uncompensated {:.4} mm: it removes {removed:.0} % of the error",
                u.mean_norm
            )
        } else {
            String::new()
        };
        format!(
            "{} leaves {:.4}{} mm mean (± one standard error over these {points} points){before}",
            c.reference.name(),
            stats.mean_norm,
            plus_minus(stats.mean_norm_standard_error),
        )
    } else {
        format!(
            "point by point against {} (mean {:.4}{} mm, ± one standard error): {} mm; a \
             difference within two standard errors is not resolved by these {points} points",
            c.reference.name(),
            stats.mean_norm,
            plus_minus(stats.mean_norm_standard_error),
            differences.join(", ")
        )
    }];
    let offset = |m: &MethodResult| {
        let s = m.position_mm.as_ref()?;
        let p = s.mean_per_axis_p_value?;
        let [x, y, z] = s.mean_per_axis.map(rounded_zero);
        Some((
            p,
            format!(
                "{} ({x:+.4}, {y:+.4}, {z:+.4}) mm, p = {}",
                m.method.name(),
                crate::baselines::p_value_text(p)
            ),
        ))
    };
    if let Some((_, text)) = offset(reference) {
        let others: Vec<String> = e
            .methods
            .iter()
            .filter(|m| m.method != c.reference)
            .filter_map(offset)
            .filter(|(p, _)| *p < OFFSET_SIGNIFICANCE)
            .map(|(_, text)| text)
            .collect();
        let also = if others.is_empty() {
            String::new()
        } else {
            format!("; at p < {OFFSET_SIGNIFICANCE} also {}", others.join(", "))
        };
        notes.push(format!(
            "offset shared by the residuals (their mean, Hotelling's T² against zero): \
             {text}{also}"
        ));
    }
    notes
}

/// ` ± se` to four decimals, or nothing without a standard error.
pub(crate) fn plus_minus(se: Option<f64>) -> String {
    se.map_or(String::new(), |se| format!(" ± {se:.4}"))
}

/// `v`, or zero where it rounds to zero at four decimals: no "-0.0000" for a signed mean.
pub(crate) fn rounded_zero(v: f64) -> f64 {
    if v.abs() < 5e-5 {
        0.0
    } else {
        v
    }
}

/// The p value below which the terminal names a method whose residuals share an offset.
const OFFSET_SIGNIFICANCE: f64 = 0.01;

/// One row of the figures as the CSV writes it and the Python package returns it, the
/// figures in full precision: those of [`terminal_table`], then the standard error of the
/// position mean and the p value of the residuals' shared offset
/// ([`ResidualStats::mean_per_axis_p_value`]); `None` where a figure does not exist.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Record {
    /// `uncompensated`, or the method's name.
    pub method: String,
    /// Points predicted.
    pub predicted: usize,
    /// Points not predicted.
    pub not_predicted: usize,
    /// Mean position residual norm, mm.
    pub position_mean_mm: Option<f64>,
    /// RMS position residual norm, mm.
    pub position_rms_mm: Option<f64>,
    /// 95th percentile (nearest rank) of the position residual norms, mm.
    pub position_p95_mm: Option<f64>,
    /// Largest position residual norm, mm.
    pub position_max_mm: Option<f64>,
    /// Mean orientation residual norm, mrad.
    pub orientation_mean_mrad: Option<f64>,
    /// RMS orientation residual norm, mrad.
    pub orientation_rms_mrad: Option<f64>,
    /// 95th percentile of the orientation residual norms, mrad.
    pub orientation_p95_mrad: Option<f64>,
    /// Largest orientation residual norm, mrad.
    pub orientation_max_mrad: Option<f64>,
    /// Standard error of the mean position residual norm, mm.
    pub position_mean_se_mm: Option<f64>,
    /// p value of the position residuals' shared offset.
    pub position_offset_p: Option<f64>,
    /// Why points were missed or a method not supported; empty otherwise.
    pub note: String,
}

/// The rows of the figures: `uncompensated`, then one per method.
pub fn records(e: &Evaluation) -> Vec<Record> {
    rows(e)
        .into_iter()
        .map(|row| {
            let [position_mean_mm, position_rms_mm, position_p95_mm, position_max_mm] =
                figures(row.position);
            let [orientation_mean_mrad, orientation_rms_mrad, orientation_p95_mrad, orientation_max_mrad] =
                figures(row.orientation);
            let [position_mean_se_mm, position_offset_p] = resolution(row.position);
            Record {
                method: row.label.to_string(),
                predicted: row.predicted,
                not_predicted: row.not_predicted,
                position_mean_mm,
                position_rms_mm,
                position_p95_mm,
                position_max_mm,
                orientation_mean_mrad,
                orientation_rms_mrad,
                orientation_p95_mrad,
                orientation_max_mrad,
                position_mean_se_mm,
                position_offset_p,
                note: row.note,
            }
        })
        .collect()
}

/// The figures as CSV: one row per method (and `uncompensated`), the fields of
/// [`Record`]; empty fields where a figure does not exist.
pub fn csv(e: &Evaluation) -> String {
    let mut out = String::from(
        "method,predicted,not_predicted,position_mean_mm,position_rms_mm,position_p95_mm,\
         position_max_mm,orientation_mean_mrad,orientation_rms_mrad,orientation_p95_mrad,\
         orientation_max_mrad,position_mean_se_mm,position_offset_p,note\n",
    );
    for r in records(e) {
        let _ = write!(out, "{},{},{}", r.method, r.predicted, r.not_predicted);
        for v in [
            r.position_mean_mm,
            r.position_rms_mm,
            r.position_p95_mm,
            r.position_max_mm,
            r.orientation_mean_mrad,
            r.orientation_rms_mrad,
            r.orientation_p95_mrad,
            r.orientation_max_mrad,
            r.position_mean_se_mm,
        ] {
            match v {
                Some(v) => {
                    let _ = write!(out, ",{v:.9}");
                }
                None => out.push(','),
            }
        }
        // A p value spans many decades: four significant digits, not nine decimals.
        match r.position_offset_p {
            Some(p) => {
                let _ = write!(out, ",{p:.3e}");
            }
            None => out.push(','),
        }
        let _ = writeln!(out, ",\"{}\"", r.note.replace('"', "\"\""));
    }
    out
}

/// The whole evaluation as pretty-printed JSON (figures, per-point predictions, and the
/// kinematic identification), written to `w` as it is encoded: a million samples' is a
/// gigabyte of text, never held beside the evaluation.
///
/// # Errors
///
/// `w`'s error; serialisation itself does not fail on plain numbers and strings.
pub fn write_json(w: &mut dyn std::io::Write, e: &Evaluation) -> Result<(), serde_json::Error> {
    serde_json::to_writer_pretty(w, e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::choice::{HarmonicsCandidate, HarmonicsChoice, HeldOut, SeriesReach};
    use crate::SplitHarmonics;

    fn split(split: usize, chosen: u8, series_reach: Option<SeriesReach>) -> SplitHarmonics {
        let candidate = |harmonics: u8, mean: f64| HarmonicsCandidate {
            harmonics,
            cv_mean_mm: Some(mean),
            noise_mm: None,
            missed: 0,
        };
        SplitHarmonics {
            split,
            choice: HarmonicsChoice {
                folds: 5,
                held_out: HeldOut::Blocks,
                candidates: vec![
                    candidate(0, 0.5184),
                    candidate(1, 0.5187),
                    candidate(2, 0.4946),
                ],
                chosen,
                series_reach,
            },
        }
    }

    /// The count chosen is said: with one split its figures and, with series that could
    /// not judge it, why blocks chose; with several, how many splits chose each count.
    #[test]
    fn the_harmonic_count_is_said_with_its_evidence() {
        assert_eq!(harmonics_note(&[]), None);
        let reach = SeriesReach {
            held_out_poses: 1000,
            within_range: 0,
        };
        let one = harmonics_note(&[split(0, 2, Some(reach))]).unwrap();
        assert_eq!(
            one,
            "harmonic count chosen on the training samples by 5 spatial blocks, each predicted \
             from the others, the model alone; not by the series held out, 0 of whose 1000 \
             poses lie within the joint angles the other series span: 2 (held-out mean mm by \
             count: 0: 0.5184, 1: 0.5187, 2: 0.4946)"
        );
        let several = harmonics_note(&[split(0, 2, None), split(1, 1, None), split(2, 2, None)]);
        assert_eq!(
            several.unwrap(),
            "harmonic count chosen on each split's training samples by 5 spatial blocks, each \
             predicted from the others, the model alone: 1 in 1 of 3, 2 in 2 of 3 splits"
        );
    }
}
