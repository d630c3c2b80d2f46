//! The evaluation as a self-contained HTML page, in this order: the figures table with
//! the noise floor; the cumulative distribution of position residual norms per method;
//! residual norm against distance from the robot base; error vectors before and after
//! compensation on a top and a side view; per-axis errors and biases; where the training
//! samples and the evaluated points lie; orientation residuals, when measured; and the
//! parameters of the kinematic identification, when a robot was given.
//!
//! The plots are inline SVG drawn with `plotters`' SVG backend alone: no font files, no
//! bitmap encoders. Text is emitted as SVG `<text>` and laid out by the browser, so the
//! page needs nothing beside itself.

use std::fmt::Write as _;

pub mod iso9283;
mod plots;

use super::{Evaluation, MethodResult, ParameterRow};
use plots::*;

/// Why the report could not be drawn.
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
}

pub(super) fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn cell(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |v| format!("{v:.4}"))
}

/// A figure: plots side by side and a caption.
fn figure(page: &mut String, svgs: &[String], caption: &str) {
    page.push_str("<figure>\n<div class=\"row\">\n");
    for svg in svgs {
        page.push_str(svg);
        page.push('\n');
    }
    let _ = writeln!(
        page,
        "</div>\n<figcaption>{caption}</figcaption>\n</figure>"
    );
}

/// The page's head, its style and its title as the first heading: every report page
/// looks alike.
fn head(title: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>{title}</title>\n<style>\
         body{{font-family:sans-serif;margin:24px;max-width:1320px;color:#222}}\
         table{{border-collapse:collapse;margin:12px 0}}\
         th,td{{border:1px solid #ccc;padding:4px 10px;text-align:right}}\
         th{{background:#f2f2f2}} td:first-child,th:first-child{{text-align:left;white-space:nowrap}}\
         td.note,th.note{{text-align:left;font-size:12px;color:#555;max-width:420px}}\
         tr.floor td{{font-style:italic;background:#fafafa}}\
         code{{background:#f6f6f6;padding:2px 4px}}\
         figure{{margin:12px 0 28px 0}} figcaption{{max-width:900px;font-size:14px;color:#444;margin-top:6px}}\
         .row{{display:flex;flex-wrap:wrap;gap:12px}}\
         .swatch{{display:inline-block;width:10px;height:10px;margin-right:6px}}\
         .legend{{list-style:none;padding:0;margin:14px 0;font-size:13px}} .legend li{{margin:3px 0}}\
         .mark{{display:inline-block;width:22px;height:0;margin-right:8px;vertical-align:middle}}\
         td.text,th.text{{text-align:left}}\
         </style>\n</head>\n<body>\n<h1>{title}</h1>\n",
        title = escape(title)
    )
}

/// The report page. `command` is the command line that produced the evaluation, shown so
/// the page says how to regenerate it.
///
/// # Errors
///
/// [`ReportError::Plot`] if a plot cannot be drawn.
pub fn html(e: &Evaluation, command: &str) -> Result<String, ReportError> {
    let orientation = e.uncompensated_orientation_mrad.is_some();
    let mut page = head("Compensation evaluation");
    let _ = write!(
        page,
        "<p>{}</p>\n<p>Command: <code>{}</code></p>\n",
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
    figures_section(&mut page, e, orientation);

    let ranked = ranked(e);
    let floor_mm = e.noise_floor.as_ref().and_then(|f| f.best_mean_mm);
    cdf_section(&mut page, e, &ranked, floor_mm)?;
    distance_section(&mut page, e, &ranked, floor_mm)?;
    // What a controller can be given: the best method a table serves.
    let served = ranked.iter().copied().find(|m| m.method.is_served());
    vectors_section(&mut page, e, served)?;
    axes_section(&mut page, e);
    locations_section(&mut page, e)?;
    orientation_section(&mut page, e)?;
    parameters_section(&mut page, e);
    page.push_str("</body>\n</html>\n");
    Ok(page)
}

/// The figures table, with the noise floor row, then what the floor, the standard errors
/// and the comparison with the best method mean, and the methods not run.
fn figures_section(page: &mut String, e: &Evaluation, orientation: bool) {
    let floor_mm = e.noise_floor.as_ref().and_then(|f| f.best_mean_mm);
    figures_header(page, floor_mm.is_some(), orientation);
    let _ = write!(
        page,
        "<tr><td>{}uncompensated</td><td>{}</td><td>0</td>{}",
        swatch(BEFORE),
        e.nominal_mm.len(),
        stat_cells(Some(&e.uncompensated_position_mm), floor_mm, true)
    );
    page.push_str(&against_best(e, None));
    if orientation {
        page.push_str(&stat_cells(
            e.uncompensated_orientation_mrad.as_ref(),
            floor_mm,
            false,
        ));
    }
    page.push_str("<td class=\"note\">the measured errors</td></tr>\n");
    for m in &e.methods {
        method_row(page, e, m, floor_mm, orientation);
    }
    if let Some(floor) = floor_mm {
        let _ = write!(
            page,
            "<tr class=\"floor\"><td>noise floor</td><td></td><td></td><td>{floor:.4}</td>\
             <td></td><td></td><td></td><td>1.00</td><td></td><td></td>"
        );
        if orientation {
            page.push_str("<td></td><td></td><td></td><td></td>");
        }
        page.push_str("<td class=\"note\">the mean a perfect predictor would leave</td></tr>\n");
    }
    page.push_str("</table>\n");
    noise_floor_paragraph(page, e);
    comparison_paragraph(page, e);
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
}

/// The heading and the figures table's header row: the ratio to the noise floor when
/// there is one, the orientation columns when measured.
fn figures_header(page: &mut String, floor: bool, orientation: bool) {
    page.push_str("<h2>Figures</h2>\n<table><tr><th>method</th><th>predicted</th><th>missed</th><th>mean mm</th><th>RMS mm</th><th>p95 mm</th><th>max mm</th>");
    if floor {
        page.push_str("<th>mean ÷ floor</th>");
    }
    page.push_str("<th>± SE mm</th><th>against best mm</th>");
    if orientation {
        page.push_str("<th>mean mrad</th><th>RMS mrad</th><th>p95 mrad</th><th>max mrad</th>");
    }
    page.push_str("<th class=\"note\">notes</th></tr>\n");
}

/// A method's row: its figures, its comparison with the best, and its note (why it did
/// not run, the points it missed, how its residual field was used).
fn method_row(
    page: &mut String,
    e: &Evaluation,
    m: &MethodResult,
    floor_mm: Option<f64>,
    orientation: bool,
) {
    let mut note = m.method.description().to_string();
    if let Some(reason) = &m.unsupported {
        note = format!("unsupported: {reason}");
    }
    if m.unsupported.is_none() {
        for line in m
            .not_predicted_summary()
            .into_iter()
            .chain(m.residual_summary())
        {
            let _ = write!(note, "; {line}");
        }
    }
    let _ = write!(
        page,
        "<tr><td>{}{}</td><td>{}</td><td>{}</td>{}",
        swatch(colour(m)),
        m.method,
        m.predicted(),
        m.not_predicted_count(),
        stat_cells(m.position_mm.as_ref(), floor_mm, true)
    );
    page.push_str(&against_best(e, Some(m.method)));
    if orientation {
        page.push_str(&stat_cells(m.orientation_mrad.as_ref(), floor_mm, false));
    }
    let _ = writeln!(page, "<td class=\"note\">{}</td></tr>", escape(&note));
}

/// The cells of one set of residual statistics: mean, RMS, p95 and max; for positions
/// (`position`) also the mean's ratio to the noise floor and its standard error.
fn stat_cells(
    s: Option<&crate::baselines::ResidualStats>,
    floor_mm: Option<f64>,
    position: bool,
) -> String {
    let mut cells = match s {
        Some(s) => [s.mean_norm, s.rms_norm, s.p95_norm, s.max_norm].map(Some),
        None => [None; 4],
    }
    .map(cell)
    .map(|c| format!("<td>{c}</td>"))
    .concat();
    if let (Some(floor), true) = (floor_mm, position) {
        let r = s.map(|s| s.mean_norm / floor);
        let _ = write!(
            cells,
            "<td>{}</td>",
            r.map_or("—".to_string(), |r| format!("{r:.2}"))
        );
    }
    if position {
        let se = s.and_then(|s| s.mean_norm_standard_error);
        let _ = write!(cells, "<td>{}</td>", cell(se));
    }
    cells
}

/// The cell of a method's paired difference from the best method, ± its standard error
/// (`None`: the measured errors, never compared).
fn against_best(e: &Evaluation, method: Option<crate::Method>) -> String {
    let Some(c) = &e.comparison else {
        return "<td>—</td>".to_string();
    };
    if method == Some(c.reference) {
        // "best" says something only beside another method.
        let alone = c.against.is_empty();
        return format!("<td>{}</td>", if alone { "—" } else { "best" });
    }
    let d = c.against.iter().find(|d| Some(d.method) == method);
    let text = d.map_or("—".to_string(), |d| {
        format!(
            "{:+.4}{}",
            d.mean_difference_mm,
            crate::output::plus_minus(d.standard_error_mm)
        )
    });
    format!("<td>{text}</td>")
}

/// What the noise floor is and how it was estimated.
fn noise_floor_paragraph(page: &mut String, e: &Evaluation) {
    let Some(f) = &e.noise_floor else {
        return;
    };
    let nugget = |n: Option<f64>| n.map_or("none".to_string(), |n| format!("{n:.5} mm²"));
    let _ = writeln!(
        page,
        "<p>Noise floor: {}. Nugget of the variogram of the {} of the {} training \
         samples: {} against Cartesian distance, {} against joint distance; their total variance \
         is {:.5} mm². The nugget is the variance no predictor can explain (measurement \
         noise and variation shorter than the sample spacing); \"mean ÷ floor\" says how \
         many times that floor a method's mean residual is.</p>",
        f.best_mean_mm.map_or(
            "no mean estimated (too few sample pairs)".to_string(),
            |m| format!("a perfect predictor would leave <b>{m:.4} mm</b> mean (Gaussian, per-axis σ² = smaller nugget / 3)")
        ),
        escape(&f.basis),
        f.samples,
        nugget(f.nugget_mm2_cartesian),
        nugget(f.nugget_mm2_joint),
        f.total_variance_mm2,
    );
}

/// What the standard errors and the comparison with the best method say.
fn comparison_paragraph(page: &mut String, e: &Evaluation) {
    let Some(c) = &e.comparison else {
        return;
    };
    let _ = writeln!(
        page,
        "<p>\"± SE\" is the standard error of the mean residual: how closely these {} \
         points pin it down. \"against best\" is, point by point over the points both \
         predicted, a method's residual minus that of <b>{}</b> (the lowest mean of the \
         methods that missed no point), ± its standard error: a point hard for one method \
         is hard for a similar one, so it resolves smaller differences between similar \
         methods than the means' standard errors suggest, and a difference within two of \
         its standard errors is not resolved by these points.</p>",
        e.nominal_mm.len(),
        c.reference
    );
}

/// The cumulative distribution of position residual norms per method.
fn cdf_section(
    page: &mut String,
    e: &Evaluation,
    ranked: &[&MethodResult],
    floor_mm: Option<f64>,
) -> Result<(), ReportError> {
    page.push_str("<h2>Distribution of position residuals</h2>\n");
    let mut curves: Vec<Curve> = ranked
        .iter()
        .map(|m| Curve {
            label: format!(
                "{} (mean {})",
                m.method,
                m.position_mm
                    .as_ref()
                    .map_or("—".to_string(), |s| format!("{:.4}", s.mean_norm))
            ),
            colour: colour(m),
            values: residuals(e, m).into_iter().map(|(_, r)| norm(r)).collect(),
        })
        .collect();
    curves.push(Curve {
        label: format!(
            "uncompensated (mean {:.4})",
            e.uncompensated_position_mm.mean_norm
        ),
        colour: BEFORE,
        values: e.measured_error_mm.iter().map(|v| norm(*v)).collect(),
    });
    let all: Vec<f64> = curves
        .iter()
        .flat_map(|c| c.values.iter().copied())
        .chain(floor_mm.map(|f| f / 4.0))
        .collect();
    let (lo, hi) = log_range(&all);
    let compensated: Vec<f64> = curves[..curves.len() - 1]
        .iter()
        .flat_map(|c| c.values.iter().copied())
        .collect();
    let zoom_hi = quantile(&compensated, 0.99).max(floor_mm.unwrap_or(0.0) * 2.0) * 1.05;
    // No method predicted anything: the linear view shows the raw errors instead.
    let zoom_hi = if zoom_hi > 0.0 { zoom_hi } else { hi };
    let sigma = floor_mm.map(|m| m / (2.0 * (2.0 / std::f64::consts::PI).sqrt()));
    let reference = sigma.map(|s| move |r: f64| maxwell_cdf(r, s));
    let reference = reference.as_ref().map(|f| f as &dyn Fn(f64) -> f64);
    let overview = cdf_svg(
        "distribution",
        "position residual norm, mm (log scale)",
        &curves,
        Axis { lo, hi, log: true },
        (520, 400),
        reference,
    )?;
    let zoom = cdf_svg(
        "distribution, compensated",
        "position residual norm, mm (linear, to the compensated 99th percentile)",
        &curves,
        Axis {
            lo: 0.0,
            hi: zoom_hi,
            log: false,
        },
        (520, 400),
        reference,
    )?;
    let floor_label = "perfect predictor (noise floor)";
    let floor_words = if floor_mm.is_some() {
        ", and the dashed curve is what a perfect predictor would leave (Gaussian noise \
         with the noise floor's nugget)"
    } else {
        ""
    };
    figure(
        page,
        &[
            overview,
            zoom,
            cdf_legend(&curves, floor_mm.map(|_| floor_label)),
        ],
        &format!(
            "The fraction of evaluated points whose position residual norm is at most x, per \
             method over the points it predicted and for the measured errors (grey): further \
             left and steeper is better{floor_words}. Left, a log x axis, on which methods \
             tens of µm apart separate and the raw errors stay on the page; right, a linear \
             x axis to the 99th percentile of the compensated residuals ({} mm), curves \
             leaving its right edge having points beyond it.",
            short(zoom_hi)
        ),
    );
    Ok(())
}

/// How many methods, best first, the distance plot shows.
const DISTANCE_METHODS: usize = 3;

/// Residual norm against distance from the base.
fn distance_section(
    page: &mut String,
    e: &Evaluation,
    ranked: &[&MethodResult],
    floor_mm: Option<f64>,
) -> Result<(), ReportError> {
    page.push_str("<h2>Residual against distance from the base</h2>\n");
    let best: Vec<&MethodResult> = ranked.iter().take(DISTANCE_METHODS).copied().collect();
    let plot = distance_svg(e, &best, floor_mm)?;
    let names: Vec<&str> = best.iter().map(|m| m.method.name()).collect();
    let which = match names.len() {
        0 => "(no method predicted any point)".to_string(),
        1 => format!("and the method with the lowest mean ({})", names[0]),
        n => format!(
            "and the {n} methods with the lowest mean ({})",
            names.join(", ")
        ),
    };
    figure(
        page,
        &plot,
        &format!(
            "Position residual norm of each evaluated point against the distance of its \
             target from the robot base origin, for the measured errors (grey) {which}; \
             the thick lines are each series' median in {} equal bins of distance. A trend \
             with distance is error a method leaves where the arm reaches far or close. The \
             y axis is logarithmic: equal heights are equal ratios.{}",
            distance_bins(e.nominal_mm.len()),
            if floor_mm.is_some() {
                " The dashed line is the noise floor's mean."
            } else {
                ""
            }
        ),
    );
    Ok(())
}

/// Error vectors before and after compensation by the best method a table serves (a
/// controller can be given nothing else), on a top and a side view.
fn vectors_section(
    page: &mut String,
    e: &Evaluation,
    best: Option<&MethodResult>,
) -> Result<(), ReportError> {
    page.push_str("<h2>Error vectors before and after compensation</h2>\n");
    let extent = {
        let all: Vec<[f64; 2]> = e
            .nominal_mm
            .iter()
            .flat_map(|p| [View::Top.project(*p), View::Side.project(*p)])
            .collect();
        let (x, _) = square_ranges(&all);
        x.end - x.start
    };
    // Arrows of the 95th-percentile error about 7 % of the panel, on a round scale.
    let scale_for = |norms: &[f64]| {
        let p95 = quantile(norms, 0.95).max(1e-9);
        let bar = nice_below(p95);
        (nice_below(0.07 * extent / p95), bar)
    };
    let before_norms: Vec<f64> = e.measured_error_mm.iter().map(|v| norm(*v)).collect();
    let before_scale = scale_for(&before_norms);
    let mut svgs = Vec::new();
    for view in [View::Top, View::Side] {
        svgs.push(arrows_svg(
            "measured error",
            view,
            &e.nominal_mm,
            &e.measured_error_mm,
            BEFORE,
            before_scale,
        )?);
    }
    let shown = |n: usize| {
        let stride = n.div_ceil(MAX_ARROWS).max(1);
        if stride > 1 {
            format!(
                " One point in {stride} is drawn ({} of {n}).",
                n.div_ceil(stride)
            )
        } else {
            String::new()
        }
    };
    figure(
        page,
        &svgs,
        &format!(
            "{}Measured error (uncompensated) at each evaluated point, {} (left) and {} \
             (right), all points projected: each arrow starts at the target and points along \
             the error, {} mm of arrow per mm of error (scale bar bottom left). Arrows that \
             agree with their neighbours are systematic error a model can learn.{}",
            swatch(BEFORE),
            View::Top.name(),
            View::Side.name(),
            short(before_scale.0),
            shown(e.nominal_mm.len())
        ),
    );
    let Some(m) = best else {
        page.push_str("<p>No method predicted any point: no residual vectors to show.</p>\n");
        return Ok(());
    };
    let list = residuals(e, m);
    let points: Vec<[f64; 3]> = list.iter().map(|(i, _)| e.nominal_mm[*i]).collect();
    let vectors: Vec<[f64; 3]> = list.iter().map(|(_, r)| *r).collect();
    let after_scale = scale_for(&vectors.iter().map(|v| norm(*v)).collect::<Vec<_>>());
    let mut svgs = Vec::new();
    for view in [View::Top, View::Side] {
        svgs.push(arrows_svg(
            "residual",
            view,
            &points,
            &vectors,
            colour(m),
            after_scale,
        )?);
    }
    figure(
        page,
        &svgs,
        &format!(
            "{}Residual after compensation by <b>{}</b>, the method with the lowest mean, \
             drawn the same way at {} mm of arrow per mm of error ({}× the scale above). \
             Arrows still agreeing with their neighbours are systematic error the method \
             missed; arrows in random directions are noise.{}",
            swatch(colour(m)),
            m.method,
            short(after_scale.0),
            short(after_scale.0 / before_scale.0),
            shown(points.len())
        ),
    );
    Ok(())
}

/// Per method: mean absolute and signed mean residual per axis.
fn axes_section(page: &mut String, e: &Evaluation) {
    page.push_str(
        "<h2>Per-axis errors</h2>\n<table><tr><th>method</th><th>points</th>\
         <th>mean |dx| mm</th><th>mean |dy| mm</th><th>mean |dz| mm</th>\
         <th>mean dx mm</th><th>mean dy mm</th><th>mean dz mm</th><th>offset p</th></tr>\n",
    );
    let row = |page: &mut String, label: String, vectors: &[[f64; 3]], p: Option<f64>| {
        let n = vectors.len().max(1) as f64;
        let abs = [0, 1, 2].map(|a| vectors.iter().map(|v| v[a].abs()).sum::<f64>() / n);
        let signed = [0, 1, 2].map(|a| vectors.iter().map(|v| v[a]).sum::<f64>() / n);
        let _ = write!(page, "<tr><td>{label}</td><td>{}</td>", vectors.len());
        for v in abs {
            let _ = write!(page, "<td>{v:.4}</td>");
        }
        for v in signed {
            let _ = write!(page, "<td>{:+.4}</td>", crate::output::rounded_zero(v));
        }
        let p = p.map_or("—".to_string(), crate::baselines::p_value_text);
        let _ = writeln!(page, "<td>{p}</td></tr>");
    };
    row(
        page,
        format!("{}uncompensated", swatch(BEFORE)),
        &e.measured_error_mm,
        e.uncompensated_position_mm.mean_per_axis_p_value,
    );
    for m in &e.methods {
        let Some(stats) = &m.position_mm else {
            continue;
        };
        let vectors: Vec<[f64; 3]> = residuals(e, m).into_iter().map(|(_, r)| r).collect();
        row(
            page,
            format!("{}{}", swatch(colour(m)), m.method),
            &vectors,
            stats.mean_per_axis_p_value,
        );
    }
    page.push_str(
        "</table>\n<p>Residual components in the base frame over the points each method \
         predicted: the mean absolute values say along which axis error remains, the signed \
         means are a bias, near zero for a method that has learnt the error. \"offset p\" \
         tests the signed means together against zero (Hotelling's T²): the chance that \
         residuals without a common offset show one this large. A small p for every good \
         method says the evaluated points share an error no model of the samples can learn: \
         a validation series measured apart (another registration, another temperature).</p>\n",
    );
}

/// Where the training samples and the evaluated points lie.
fn locations_section(page: &mut String, e: &Evaluation) -> Result<(), ReportError> {
    page.push_str("<h2>Where the samples and evaluated points lie</h2>\n");
    let svgs = vec![locations_svg(e, View::Top)?, locations_svg(e, View::Side)?];
    let same = e.training_nominal_mm == e.nominal_mm;
    // A table evaluated on its own keeps its samples' positions to itself.
    let training = match e.training_nominal_mm.len() {
        0 => "table's samples (not in the table file: not drawn)".to_string(),
        n => format!("{n} training samples ({}dark grey dots)", swatch(TRAINING)),
    };
    figure(
        page,
        &svgs,
        &format!(
            "Nominal positions of the {training} and the {} \
             evaluated points ({}blue rings), {} (left) and {} (right), base frame, equal \
             scales on both axes; evaluated points outside the cloud of samples are \
             extrapolation.{}",
            e.nominal_mm.len(),
            swatch(EVALUATED),
            View::Top.name(),
            View::Side.name(),
            if same {
                " In cross-validation every sample is evaluated once, predicted from the \
                 other folds, so both sets are the same."
            } else {
                ""
            }
        ),
    );
    Ok(())
}

/// Orientation residuals, or a line saying there are none.
fn orientation_section(page: &mut String, e: &Evaluation) -> Result<(), ReportError> {
    let (Some(measured), Some(stats)) = (
        &e.measured_rotation_error_rad,
        &e.uncompensated_orientation_mrad,
    ) else {
        page.push_str(
            "<p class=\"note\">No orientation errors were measured in both sets: no \
             orientation plot.</p>\n",
        );
        return Ok(());
    };
    page.push_str("<h2>Distribution of orientation residuals</h2>\n");
    let mut curves: Vec<Curve> = e
        .methods
        .iter()
        .filter_map(|m| {
            let s = m.orientation_mrad.as_ref()?;
            Some((s.mean_norm, m))
        })
        .collect::<Vec<_>>()
        .into_iter()
        .map(|(mean, m)| Curve {
            label: format!("{} (mean {mean:.4})", m.method),
            colour: colour(m),
            values: orientation_norms(e, m),
        })
        .collect();
    curves.sort_by(|a, b| {
        let mean = |c: &Curve| c.values.iter().sum::<f64>() / c.values.len().max(1) as f64;
        mean(a).total_cmp(&mean(b))
    });
    curves.push(Curve {
        label: format!("uncompensated (mean {:.4})", stats.mean_norm),
        colour: BEFORE,
        values: measured.iter().map(|r| norm(*r) * 1e3).collect(),
    });
    let all: Vec<f64> = curves
        .iter()
        .flat_map(|c| c.values.iter().copied())
        .collect();
    let (lo, hi) = log_range(&all);
    let plot = [
        cdf_svg(
            "orientation distribution",
            "orientation residual norm, mrad (log scale)",
            &curves,
            Axis { lo, hi, log: true },
            (760, 420),
            None,
        )?,
        cdf_legend(&curves, None),
    ];
    let missing: Vec<&str> = e
        .methods
        .iter()
        .filter(|m| m.position_mm.is_some() && m.orientation_mrad.is_none())
        .map(|m| m.method.name())
        .collect();
    figure(
        page,
        &plot,
        &format!(
            "The fraction of evaluated points whose orientation residual norm (rotation \
             vector, base frame) is at most x, per method that predicts orientation and for \
             the measured errors (grey), on a log x axis: further left is better.{}",
            if missing.is_empty() {
                String::new()
            } else {
                format!(" Not predicting orientation: {}.", missing.join(", "))
            }
        ),
    );
    Ok(())
}

/// The order of the parameter table: identified parameters by |value| / SE, the most
/// significant first, then those held at nominal, then the unidentifiable ones, each in
/// the identification's order.
fn parameter_order(rows: &[ParameterRow]) -> Vec<&ParameterRow> {
    let group = |r: &ParameterRow| match r.status {
        "identified" => 0,
        "held" => 1,
        _ => 2,
    };
    let significance = |r: &ParameterRow| match (r.status, r.standard_error) {
        ("identified", Some(se)) if se > 0.0 => r.value.abs() / se,
        ("identified", _) => f64::INFINITY,
        _ => 0.0,
    };
    let mut sorted: Vec<&ParameterRow> = rows.iter().collect();
    sorted.sort_by(|a, b| {
        group(a)
            .cmp(&group(b))
            .then(significance(b).total_cmp(&significance(a)))
    });
    sorted
}

/// The first identification's summary and parameter table.
fn parameters_section(page: &mut String, e: &Evaluation) {
    let Some(c) = e.calibrations.first() else {
        return;
    };
    let _ = write!(
        page,
        "<h2>Kinematic identification{}</h2>\n<p>{}; condition number of the identified \
         parameters' scaled Jacobian {:.1}; position RMS over the training samples {:.4} mm \
         before, {:.4} mm after{}; {} iterations{}.</p>\n",
        if e.calibrations.len() > 1 {
            format!(", fold {} of {}", c.split + 1, e.calibrations.len())
        } else {
            String::new()
        },
        c.counts(),
        c.condition_number,
        c.initial_position_rms_mm,
        c.position_rms_mm,
        c.orientation_rms_mrad
            .map_or(String::new(), |r| format!(", orientation RMS {r:.4} mrad")),
        c.iterations,
        if c.converged { "" } else { " (not converged)" }
    );
    page.push_str(
        "<p>Identified parameters first, the most significant (largest |value| / SE) at \
         the top; then those held at nominal, then the unidentifiable ones, in the \
         model's order. Lengths in mm, angles in mrad.</p>\n<table><tr><th>parameter</th>\
         <th class=\"text\">unit</th><th>value</th><th>SE</th><th>|value| / SE</th>\
         <th class=\"text\">strongest correlation</th><th class=\"text\">status</th><th class=\"note\">reason</th></tr>\n",
    );
    for r in parameter_order(&c.parameters) {
        let unit = r.shown_unit().1;
        let value = r.value_text();
        let se = r.standard_error_text();
        let ratio = match (r.is_identified(), r.standard_error) {
            (true, Some(s)) if s > 0.0 => format!("{:.1}", r.value.abs() / s),
            _ => "—".to_string(),
        };
        let correlation = match (&r.correlated_with, r.correlation) {
            (Some(p), Some(rho)) => format!("{rho:+.2} with {}", escape(p)),
            _ => "—".to_string(),
        };
        let _ = writeln!(
            page,
            "<tr><td>{}</td><td class=\"text\">{unit}</td><td>{value}</td><td>{se}</td>\
             <td>{ratio}</td><td class=\"text\">{correlation}</td><td class=\"text\">{}</td>\
             <td class=\"note\">{}</td></tr>",
            escape(&r.name),
            r.status,
            escape(&r.reason)
        );
    }
    page.push_str("</table>\n");
    if e.calibrations.len() > 1 {
        page.push_str("<p>The other folds' identifications are in the JSON output.</p>\n");
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use adwi_robot::Robot;
    use adwi_samples::{read_samples, ColumnMap, SampleSet};

    use super::*;
    use crate::{evaluate, EvalOptions, Method, Protocol};

    fn shipped(file: &str) -> SampleSet {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables/kr150-2");
        read_samples(&path.join(file), &ColumnMap::default()).expect("shipped samples")
    }

    /// The KR150-2 samples and their first 40 validation points, without orientation
    /// errors when `orientation` is false.
    fn inputs(orientation: bool) -> (SampleSet, SampleSet) {
        let mut samples = shipped("samples.csv");
        let validation = shipped("validation.csv");
        let mut validation = validation.subset(&(0..40).collect::<Vec<_>>());
        if !orientation {
            samples.rotation_error_rad = None;
            validation.rotation_error_rad = None;
        }
        (samples, validation)
    }

    fn page(orientation: bool, robot: bool) -> String {
        let (samples, validation) = inputs(orientation);
        let mut methods = vec![Method::Paper, Method::Idw];
        let robot = robot.then(|| {
            methods.push(Method::Kinematic);
            let path =
                Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables/kr150-2/robot.toml");
            Robot::load(path).expect("shipped robot")
        });
        let options = EvalOptions {
            methods: Some(methods),
            robot,
            ..EvalOptions::default()
        };
        let e =
            evaluate(&samples, &Protocol::Validation(validation), &options).expect("evaluation");
        html(&e, "tablec eval samples.csv --validation validation.csv").expect("page")
    }

    /// The page's sections by their `<h2>` heading, in order, each with its text.
    fn sections(page: &str) -> Vec<(String, String)> {
        page.split("<h2>")
            .skip(1)
            .map(|s| {
                let (heading, rest) = s.split_once("</h2>").expect("closed heading");
                (heading.to_string(), rest.to_string())
            })
            .collect()
    }

    /// Which sections a page must have, with how many plots and captioned figures each.
    const POSITION_SECTIONS: [(&str, usize, usize); 6] = [
        ("Figures", 0, 0),
        ("Distribution of position residuals", 2, 1),
        ("Residual against distance from the base", 1, 1),
        // Before and after, each a top and a side view.
        ("Error vectors before and after compensation", 4, 2),
        ("Per-axis errors", 0, 0),
        ("Where the samples and evaluated points lie", 2, 1),
    ];
    const ORIENTATION: (&str, usize, usize) = ("Distribution of orientation residuals", 1, 1);
    const IDENTIFICATION: (&str, usize, usize) = ("Kinematic identification", 0, 0);

    fn check_sections(page: &str, expected: &[(&str, usize, usize)]) {
        let found = sections(page);
        let headings: Vec<&str> = found.iter().map(|(h, _)| h.as_str()).collect();
        let wanted: Vec<&str> = expected.iter().map(|(h, _, _)| *h).collect();
        assert_eq!(headings, wanted);
        for ((heading, text), (_, plots, figures)) in found.iter().zip(expected) {
            assert_eq!(text.matches("<svg").count(), *plots, "{heading}");
            assert_eq!(text.matches("<figcaption>").count(), *figures, "{heading}");
        }
    }

    /// A self-contained HTML5 page: nothing loaded from elsewhere.
    fn check_self_contained(page: &str) {
        assert!(page.starts_with("<!DOCTYPE html>\n<html lang=\"en\">"));
        assert!(page.trim_end().ends_with("</body>\n</html>"));
        for external in ["<img", "<script", "<link", "src=", "url(", "@import"] {
            assert!(!page.contains(external), "{external}");
        }
        let without_namespaces = page.replace("xmlns=\"http://www.w3.org/2000/svg\"", "");
        assert!(!without_namespaces.contains("http"), "a link in the page");
    }

    #[test]
    fn a_run_with_a_robot_and_orientation_has_every_section() {
        let page = page(true, true);
        check_self_contained(&page);
        let mut expected = POSITION_SECTIONS.to_vec();
        expected.push(ORIENTATION);
        expected.push(IDENTIFICATION);
        check_sections(&page, &expected);
        // The noise floor, in its row, its column and its line.
        assert!(page.contains("<td>noise floor</td>"));
        assert!(page.contains("<th>mean ÷ floor</th>"));
        assert!(page.contains("Noise floor: a perfect predictor would leave"));
        assert!(page.contains("perfect predictor (noise floor)"));
        // What the points resolve: each mean's standard error, the paired difference from
        // the best method (which the page names), and each residual offset's test.
        assert!(page.contains("<th>± SE mm</th><th>against best mm</th>"));
        assert_eq!(page.matches("<td>best</td>").count(), 1);
        assert!(page.contains("a method's residual minus that of <b>"));
        assert!(page.contains("<th>offset p</th>"));
        // Axis labels carry units and frames.
        for label in [
            "x, mm (base frame)",
            "y, mm (base frame)",
            "z, mm (base frame)",
            "position residual norm, mm (log scale)",
            "orientation residual norm, mrad (log scale)",
        ] {
            assert!(page.contains(label), "{label}");
        }
        assert!(page.contains("mm error = "), "a scale bar");
        // The parameter table, identified first.
        let table = &page[page.find("<th>parameter</th>").expect("parameter table")..];
        let first_held = table.find(">held<").expect("a held parameter");
        let first_unidentifiable = table.find(">unidentifiable<").expect("unidentifiable");
        let last_identified = table.rfind(">identified<").expect("identified");
        assert!(last_identified < first_held && first_held < first_unidentifiable);
        assert!(!page.contains("No orientation errors were measured"));
    }

    #[test]
    fn a_run_without_robot_or_orientation_leaves_those_sections_out() {
        let page = page(false, false);
        check_self_contained(&page);
        check_sections(&page, &POSITION_SECTIONS);
        assert!(page.contains("No orientation errors were measured"));
        assert!(!page.contains("mrad"));
        assert!(!page.contains("Kinematic identification"));
    }

    #[test]
    fn orientation_without_a_robot_has_its_section() {
        let page = page(true, false);
        let mut expected = POSITION_SECTIONS.to_vec();
        expected.push(ORIENTATION);
        check_sections(&page, &expected);
    }

    #[test]
    fn a_run_where_no_method_predicts_still_shows_the_measured_errors() {
        // One sample off the lattice: the lattice method cannot run.
        let (mut samples, validation) = inputs(false);
        samples.nominal_mm[0][0] += 0.37;
        let options = EvalOptions {
            methods: Some(vec![Method::Grid]),
            ..EvalOptions::default()
        };
        let e =
            evaluate(&samples, &Protocol::Validation(validation), &options).expect("evaluation");
        assert!(e.methods[0].unsupported.is_some());
        let page = html(&e, "tablec eval").expect("page");
        check_self_contained(&page);
        let mut expected = POSITION_SECTIONS.to_vec();
        expected[3] = ("Error vectors before and after compensation", 2, 1);
        check_sections(&page, &expected);
        assert!(page.contains("No method predicted any point"));
    }

    fn row(name: &str, status: &'static str, value: f64, se: Option<f64>) -> ParameterRow {
        ParameterRow {
            name: name.to_string(),
            unit: "mm",
            value,
            held_estimate: None,
            standard_error: se,
            correlated_with: None,
            correlation: None,
            status,
            reason: String::new(),
        }
    }

    #[test]
    fn parameters_are_ordered_identified_by_significance_then_held_then_unidentifiable() {
        let rows = [
            row("u", "unidentifiable", 0.0, None),
            row("weak", "identified", 0.1, Some(0.05)),
            row("h", "held", 0.0, Some(0.1)),
            row("strong", "identified", -0.5, Some(0.01)),
            row("middle", "identified", 0.3, Some(0.03)),
        ];
        let names: Vec<&str> = parameter_order(&rows)
            .iter()
            .map(|r| r.name.as_str())
            .collect();
        assert_eq!(names, ["strong", "middle", "weak", "h", "u"]);
    }

    #[test]
    fn maxwell_distribution_matches_the_noise_floor_mean() {
        // The noise floor's best mean is the mean of Maxwell's distribution; its median
        // lies just below the mean, and the distribution runs from 0 to 1.
        let sigma = 0.05;
        let mean = 2.0 * sigma * (2.0 / std::f64::consts::PI).sqrt();
        assert!(maxwell_cdf(0.0, sigma).abs() < 1e-6);
        assert!((maxwell_cdf(20.0 * sigma, sigma) - 1.0).abs() < 1e-6);
        let at_mean = maxwell_cdf(mean, sigma);
        assert!((0.5..0.6).contains(&at_mean), "{at_mean}");
    }

    #[test]
    fn log_ticks_are_one_two_five() {
        assert_eq!(log_ticks(0.03, 0.6), [0.05, 0.1, 0.2, 0.5]);
        assert_eq!(short(0.1), "0.1");
        assert_eq!(short(-700.0), "-700");
        assert_eq!(short(0.00005), "0.00005");
    }
}
