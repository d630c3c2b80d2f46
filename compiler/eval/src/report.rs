//! The evaluation as a self-contained HTML page: the figures table, residual histograms
//! before and after compensation per method, and residual norm against distance from the
//! robot base, as inline SVG.
//!
//! The plots are drawn with `plotters`' SVG backend alone: no font files, no bitmap
//! encoders. Text is emitted as SVG `<text>` and laid out by the browser, so the page
//! needs nothing beside itself.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::{Evaluation, MethodResult};

/// Why the report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A plot could not be drawn.
    #[error("cannot draw the {plot} plot: {message}")]
    Plot {
        /// Which plot.
        plot: String,
        /// The backend's message.
        message: String,
    },
    /// The page could not be written.
    #[error("cannot write {path}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// One colour per method, in [`super::Method::ALL`] order; grey is "uncompensated".
const COLOURS: [RGBColor; 7] = [
    RGBColor(31, 119, 180),
    RGBColor(23, 190, 207),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(148, 103, 189),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
];
const BEFORE: RGBColor = RGBColor(150, 150, 150);

fn colour(m: &MethodResult) -> RGBColor {
    let index = super::Method::ALL
        .iter()
        .position(|x| *x == m.method)
        .unwrap_or(0);
    COLOURS[index % COLOURS.len()]
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Residual norms (mm) of a method at the points it predicted, with the point index.
fn residual_norms(e: &Evaluation, m: &MethodResult) -> Vec<(usize, f64)> {
    m.predictions
        .iter()
        .enumerate()
        .filter_map(|(i, p)| {
            let p = p.as_ref()?;
            let measured = e.measured_error_mm[i];
            Some((
                i,
                norm([0, 1, 2].map(|a| measured[a] - p.position_error_mm[a])),
            ))
        })
        .collect()
}

fn plot_error<E: std::fmt::Debug>(plot: &str) -> impl Fn(E) -> ReportError + '_ {
    move |e| ReportError::Plot {
        plot: plot.to_string(),
        message: format!("{e:?}"),
    }
}

/// Counts of `values` in `bins` equal bins over `[0, top]` (values above go in the last).
fn histogram(values: &[f64], top: f64, bins: usize) -> Vec<usize> {
    let mut counts = vec![0; bins];
    for &v in values {
        let b = ((v / top) * bins as f64).floor() as usize;
        counts[b.min(bins - 1)] += 1;
    }
    counts
}

/// Histogram of a method's position residual norms after compensation, with the raw error
/// norms before when `with_before` (on the raw errors' scale, where the residuals are a
/// bar or two) or alone (on the residuals' own scale, to show their spread). The axis is
/// shared by every method's panel so panels compare.
fn histogram_svg(
    e: &Evaluation,
    m: &MethodResult,
    top_mm: f64,
    with_before: bool,
) -> Result<String, ReportError> {
    const BINS: usize = 30;
    let before: Vec<f64> = if with_before {
        e.measured_error_mm.iter().map(|v| norm(*v)).collect()
    } else {
        Vec::new()
    };
    let after: Vec<f64> = residual_norms(e, m).into_iter().map(|(_, n)| n).collect();
    let hb = histogram(&before, top_mm, BINS);
    let ha = histogram(&after, top_mm, BINS);
    let highest = hb.iter().chain(&ha).copied().max().unwrap_or(1).max(1);
    let mut svg = String::new();
    {
        let name = format!("{} histogram", m.method);
        let err = plot_error(&name);
        let root = SVGBackend::with_string(&mut svg, (420, 260)).into_drawing_area();
        root.fill(&WHITE).map_err(&err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{} — position residual norm", m.method),
                ("sans-serif", 16),
            )
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(40)
            .build_cartesian_2d(0.0..top_mm, 0.0..(highest as f64 * 1.1))
            .map_err(&err)?;
        chart
            .configure_mesh()
            .x_desc("residual norm, mm")
            .y_desc("points")
            .label_style(("sans-serif", 11))
            .draw()
            .map_err(&err)?;
        let width = top_mm / BINS as f64;
        let bars = |counts: &[usize], style: ShapeStyle, label: &str| {
            let label = label.to_string();
            (counts.to_vec(), style, label, width)
        };
        let series = [
            bars(&hb, BEFORE.mix(0.45).filled(), "before (raw error)"),
            bars(&ha, colour(m).mix(0.75).filled(), "after compensation"),
        ];
        for (counts, style, label, width) in series.into_iter().skip(usize::from(!with_before)) {
            chart
                .draw_series(counts.iter().enumerate().filter(|(_, &c)| c > 0).map(
                    move |(b, &c)| {
                        let x0 = b as f64 * width;
                        Rectangle::new([(x0, 0.0), (x0 + width, c as f64)], style)
                    },
                ))
                .map_err(&err)?
                .label(label)
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], style));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.3))
            .label_font(("sans-serif", 11))
            .draw()
            .map_err(&err)?;
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

/// Residual norm against the point's distance from the robot base origin, every method
/// and the raw errors in one scatter plot.
fn distance_svg(e: &Evaluation) -> Result<String, ReportError> {
    let distance: Vec<f64> = e.nominal_mm.iter().map(|p| norm(*p)).collect();
    let before: Vec<f64> = e.measured_error_mm.iter().map(|v| norm(*v)).collect();
    let (lo, hi) = distance
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), d| {
            (lo.min(*d), hi.max(*d))
        });
    let pad = ((hi - lo) * 0.05).max(1.0);
    let top = before.iter().copied().fold(0.0, f64::max).max(1e-3) * 1.1;
    let mut svg = String::new();
    {
        let err = plot_error("distance");
        let root = SVGBackend::with_string(&mut svg, (860, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(&err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Position residual norm against distance from the base",
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d((lo - pad)..(hi + pad), 0.0..top)
            .map_err(&err)?;
        chart
            .configure_mesh()
            .x_desc("distance of the target from the base origin, mm")
            .y_desc("residual norm, mm")
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(&err)?;
        let style = BEFORE.filled();
        chart
            .draw_series(
                distance
                    .iter()
                    .zip(&before)
                    .map(move |(d, b)| Circle::new((*d, *b), 3, style)),
            )
            .map_err(&err)?
            .label("uncompensated")
            .legend(move |(x, y)| Circle::new((x + 5, y), 3, style));
        for m in e.methods.iter().filter(|m| m.unsupported.is_none()) {
            let style = colour(m).filled();
            let points: Vec<(f64, f64)> = residual_norms(e, m)
                .into_iter()
                .map(|(i, n)| (distance[i], n))
                .collect();
            chart
                .draw_series(
                    points
                        .into_iter()
                        .map(move |(d, n)| Circle::new((d, n), 3, style)),
                )
                .map_err(&err)?
                .label(m.method.name())
                .legend(move |(x, y)| Circle::new((x + 5, y), 3, style));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.3))
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(&err)?;
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn cell(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |v| format!("{v:.4}"))
}

/// The report page. `command` is the command line that produced the evaluation, shown so
/// the page says how to regenerate it.
///
/// # Errors
///
/// [`ReportError::Plot`] if a plot cannot be drawn.
pub fn html(e: &Evaluation, command: &str) -> Result<String, ReportError> {
    let orientation = e.uncompensated_orientation_mrad.is_some();
    let mut page = String::new();
    let _ = write!(
        page,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>Compensation evaluation</title>\n<style>\
         body{{font-family:sans-serif;margin:24px;max-width:1320px;color:#222}}\
         table{{border-collapse:collapse;margin:12px 0}}\
         th,td{{border:1px solid #ccc;padding:4px 10px;text-align:right}}\
         th{{background:#f2f2f2}} td:first-child,th:first-child{{text-align:left}}\
         td.note,th.note{{text-align:left;font-size:12px;color:#555;max-width:420px}}\
         code{{background:#f6f6f6;padding:2px 4px}}\
         .grid{{display:flex;flex-wrap:wrap;gap:8px}} .swatch{{display:inline-block;width:10px;height:10px;margin-right:6px}}\
         </style></head><body>\n<h1>Compensation evaluation</h1>\n<p>{}</p>\n\
         <p>Command: <code>{}</code></p>\n",
        escape(&e.protocol),
        escape(command)
    );
    page.push_str(
        "<p>Residual = measured error − predicted error, the error that would remain after \
         compensation; figures are over residual norms, base frame. Position in mm",
    );
    page.push_str(if orientation {
        ", orientation in mrad.</p>\n"
    } else {
        "; no orientation was measured.</p>\n"
    });
    page.push_str("<h2>Figures</h2>\n<table><tr><th>method</th><th>predicted</th><th>missed</th><th>mean mm</th><th>RMS mm</th><th>p95 mm</th><th>max mm</th>");
    if orientation {
        page.push_str("<th>mean mrad</th><th>RMS mrad</th><th>p95 mrad</th><th>max mrad</th>");
    }
    page.push_str("<th class=\"note\">notes</th></tr>\n");
    let stat_cells = |s: Option<&crate::baselines::ResidualStats>| {
        match s {
            Some(s) => [s.mean_norm, s.rms_norm, s.p95_norm, s.max_norm].map(Some),
            None => [None; 4],
        }
        .map(cell)
        .map(|c| format!("<td>{c}</td>"))
        .concat()
    };
    let _ = write!(
        page,
        "<tr><td><span class=\"swatch\" style=\"background:rgb({},{},{})\"></span>uncompensated</td><td>{}</td><td>0</td>{}",
        BEFORE.0,
        BEFORE.1,
        BEFORE.2,
        e.nominal_mm.len(),
        stat_cells(Some(&e.uncompensated_position_mm))
    );
    if orientation {
        page.push_str(&stat_cells(e.uncompensated_orientation_mrad.as_ref()));
    }
    page.push_str("<td class=\"note\">the measured errors</td></tr>\n");
    for m in &e.methods {
        let c = colour(m);
        let mut note = m.method.description().to_string();
        if let Some(reason) = &m.unsupported {
            note = format!("unsupported: {reason}");
        }
        if m.unsupported.is_none() {
            for line in m.not_predicted_summary() {
                let _ = write!(note, "; {line}");
            }
        }
        let _ = write!(
            page,
            "<tr><td><span class=\"swatch\" style=\"background:rgb({},{},{})\"></span>{}</td><td>{}</td><td>{}</td>{}",
            c.0,
            c.1,
            c.2,
            m.method,
            m.predicted(),
            m.not_predicted_count(),
            stat_cells(m.position_mm.as_ref())
        );
        if orientation {
            page.push_str(&stat_cells(m.orientation_mrad.as_ref()));
        }
        let _ = writeln!(page, "<td class=\"note\">{}</td></tr>", escape(&note));
    }
    page.push_str("</table>\n");
    if !e.skipped.is_empty() {
        page.push_str("<p>Not run: ");
        let list: Vec<String> = e
            .skipped
            .iter()
            .map(|(m, why)| format!("<b>{m}</b> ({})", escape(why)))
            .collect();
        page.push_str(&list.join(", "));
        page.push_str("</p>\n");
    }

    page.push_str(
        "<h2>Residual histograms, before and after compensation</h2>\n<div class=\"grid\">\n",
    );
    let top_mm = e
        .measured_error_mm
        .iter()
        .map(|v| norm(*v))
        .fold(0.0, f64::max)
        .max(1e-3)
        * 1.02;
    for m in e.methods.iter().filter(|m| m.unsupported.is_none()) {
        page.push_str(&histogram_svg(e, m, top_mm, true)?);
        page.push('\n');
    }
    page.push_str(
        "</div>\n<h2>Residuals after compensation, on their own scale</h2>\n<div class=\"grid\">\n",
    );
    let compensated = e.methods.iter().filter(|m| m.unsupported.is_none());
    let residual_top_mm = compensated
        .clone()
        .flat_map(|m| residual_norms(e, m))
        .map(|(_, n)| n)
        .fold(0.0, f64::max)
        .max(1e-3)
        * 1.02;
    for m in compensated {
        page.push_str(&histogram_svg(e, m, residual_top_mm, false)?);
        page.push('\n');
    }
    page.push_str("</div>\n<h2>Residual against position</h2>\n");
    page.push_str(&distance_svg(e)?);
    page.push('\n');

    for c in &e.calibrations {
        let _ = write!(
            page,
            "<h2>Kinematic identification{}</h2>\n<p>{} parameters identified, condition \
             number of their scaled Jacobian {:.1}; position RMS over the training samples \
             {:.4} mm before, {:.4} mm after{}; {} iterations{}.</p>\n<table><tr><th>parameter</th><th>value (mm or mrad)</th></tr>\n",
            if e.calibrations.len() > 1 {
                format!(", fold {}", c.split + 1)
            } else {
                String::new()
            },
            c.identified.len(),
            c.condition_number,
            c.initial_position_rms_mm,
            c.position_rms_mm,
            c.orientation_rms_mrad
                .map_or(String::new(), |r| format!(", orientation RMS {r:.4} mrad")),
            c.iterations,
            if c.converged { "" } else { " (not converged)" }
        );
        for (name, value) in &c.identified {
            // Angles are stored in rad; shown in mrad like every other angle here.
            let angle = !(name.starts_with("Δa")
                || name.starts_with("Δd")
                || name == "tool x"
                || name == "tool y"
                || name == "tool z"
                || name == "base x"
                || name == "base y"
                || name == "base z");
            let shown = if angle { value * 1e3 } else { *value };
            let _ = writeln!(
                page,
                "<tr><td>{}</td><td>{shown:.5}</td></tr>",
                escape(name)
            );
        }
        page.push_str("</table>\n");
        if !c.unidentifiable.is_empty() {
            let list: Vec<String> = c
                .unidentifiable
                .iter()
                .map(|(name, ratio)| format!("{} ({ratio:.1e})", escape(name)))
                .collect();
            let _ = writeln!(
                page,
                "<p>Not identifiable from these data (independent fraction of the scaled \
                 Jacobian column in brackets), held at nominal: {}.</p>",
                list.join(", ")
            );
        }
        if e.calibrations.len() > 1 {
            page.push_str("<p>(Further folds are in the JSON output.)</p>\n");
            break;
        }
    }
    page.push_str("</body></html>\n");
    Ok(page)
}

/// Writes the report page to `dir/index.html`, creating `dir` if needed; returns the
/// page's path.
///
/// # Errors
///
/// [`ReportError::Write`] if the directory or file cannot be written, and the errors of
/// [`html`].
pub fn write(e: &Evaluation, command: &str, dir: &Path) -> Result<PathBuf, ReportError> {
    let page = html(e, command)?;
    let path = dir.join("index.html");
    std::fs::create_dir_all(dir)
        .and_then(|()| std::fs::write(&path, page))
        .map_err(|source| ReportError::Write {
            path: path.clone(),
            source,
        })?;
    Ok(path)
}
