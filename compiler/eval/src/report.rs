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

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Evaluation, MethodResult, ParameterRow};

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

/// One colour per method, in [`super::Method::ALL`] order, then a table scored as built;
/// grey is "uncompensated".
const COLOURS: [RGBColor; 12] = [
    RGBColor(31, 119, 180),
    RGBColor(23, 190, 207),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(188, 189, 34),
    RGBColor(148, 103, 189),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(227, 119, 194),
    RGBColor(0, 0, 0),
    RGBColor(255, 187, 120),
    RGBColor(0, 128, 128),
];
const BEFORE: RGBColor = RGBColor(150, 150, 150);
/// Training samples on the map of the workspace.
const TRAINING: RGBColor = RGBColor(60, 60, 60);
/// Evaluated points on the map of the workspace.
const EVALUATED: RGBColor = RGBColor(31, 119, 180);
/// The noise floor's reference lines.
const FLOOR: RGBColor = RGBColor(0, 0, 0);

const FONT: &str = "sans-serif";

fn colour(m: &MethodResult) -> RGBColor {
    let index = super::Method::ALL
        .iter()
        .position(|x| *x == m.method)
        .unwrap_or(super::Method::ALL.len());
    COLOURS[index % COLOURS.len()]
}

fn css(c: RGBColor) -> String {
    format!("rgb({},{},{})", c.0, c.1, c.2)
}

fn swatch(c: RGBColor) -> String {
    format!(
        "<span class=\"swatch\" style=\"background:{}\"></span>",
        css(c)
    )
}

/// How a legend entry is drawn.
#[derive(Clone, Copy)]
enum Mark {
    Line,
    Dashed,
}

/// A legend in HTML beside a plot: label and mark per entry, in order.
fn legend(entries: &[(String, RGBColor, Mark)]) -> String {
    let mut out = String::from("<ul class=\"legend\">");
    for (label, c, mark) in entries {
        let style = match mark {
            Mark::Line => format!("border-top:3px solid {}", css(*c)),
            Mark::Dashed => format!("border-top:2px dashed {}", css(*c)),
        };
        let _ = write!(
            out,
            "<li><span class=\"mark\" style=\"{style}\"></span>{}</li>",
            escape(label)
        );
    }
    out.push_str("</ul>");
    out
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Position residuals (mm, base frame) of a method at the points it predicted, with the
/// point index.
fn residuals(e: &Evaluation, m: &MethodResult) -> Vec<(usize, [f64; 3])> {
    m.position_residuals(&e.measured_error_mm)
}

/// Orientation residual norms (mrad) of a method at the points where it predicted an
/// orientation, when orientation was measured.
fn orientation_norms(e: &Evaluation, m: &MethodResult) -> Vec<f64> {
    let Some(measured) = &e.measured_rotation_error_rad else {
        return Vec::new();
    };
    m.predictions
        .iter()
        .enumerate()
        .filter_map(|(i, p)| {
            let r = p.as_ref()?.orientation_error_rad?;
            Some(norm([0, 1, 2].map(|a| (measured[i][a] - r[a]) * 1e3)))
        })
        .collect()
}

/// The methods that ran, best (lowest mean position residual) first.
fn ranked(e: &Evaluation) -> Vec<&MethodResult> {
    let mut list: Vec<&MethodResult> = e
        .methods
        .iter()
        .filter(|m| m.position_mm.is_some())
        .collect();
    list.sort_by(|a, b| {
        let mean = |m: &MethodResult| m.position_mm.as_ref().map_or(f64::MAX, |s| s.mean_norm);
        mean(a).total_cmp(&mean(b))
    });
    list
}

fn plot_error<E: std::fmt::Debug>(plot: &str) -> impl Fn(E) -> ReportError + '_ {
    move |e| ReportError::Plot {
        plot: plot.to_string(),
        message: format!("{e:?}"),
    }
}

/// A number with about three significant digits and no trailing zeros.
fn short(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let decimals = (2 - x.abs().log10().floor() as i32).clamp(0, 9) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// The largest of 1, 2, 5 × 10ⁿ not above `x` (`x` > 0).
fn nice_below(x: f64) -> f64 {
    let decade = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|v| *v <= x * (1.0 + 1e-9))
        .unwrap_or(decade)
}

/// The value at quantile `q` of `values` (nearest rank), 0 when empty.
fn quantile(values: &[f64], q: f64) -> f64 {
    let mut sorted: Vec<f64> = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    match sorted.len() {
        0 => 0.0,
        n => sorted[((q * n as f64).ceil() as usize).clamp(1, n) - 1],
    }
}

/// Labelled values of a log axis from `lo` to `hi`: 1, 2, 5 × 10ⁿ.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let first = lo.log10().floor() as i32;
    let last = hi.log10().ceil() as i32;
    (first..=last)
        .flat_map(|n| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(n)))
        .filter(|v| *v >= lo && *v <= hi)
        .collect()
}

/// The error function, Abramowitz and Stegun 7.1.26 (absolute error below 1.5e-7).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let y = 1.0 - poly * (-x * x).exp();
    y.copysign(x)
}

/// The cumulative distribution of the norm of a Gaussian vector with per-axis deviation
/// `sigma` (Maxwell's), at `r`.
fn maxwell_cdf(r: f64, sigma: f64) -> f64 {
    let u = r / sigma;
    erf(u / std::f64::consts::SQRT_2)
        - (2.0 / std::f64::consts::PI).sqrt() * u * (-u * u / 2.0).exp()
}

/// One curve of a cumulative distribution plot.
struct Curve {
    label: String,
    colour: RGBColor,
    values: Vec<f64>,
}

/// The mesh lines between labelled ones: faint, so that the data stand out.
fn faint() -> ShapeStyle {
    BLACK.mix(0.03).stroke_width(1)
}

/// The x axis of a distribution plot.
#[derive(Clone, Copy)]
struct Axis {
    lo: f64,
    hi: f64,
    log: bool,
}

impl Axis {
    /// Where a value lies on the plot's own (linear) coordinate.
    fn place(self, v: f64) -> f64 {
        if self.log {
            v.max(self.lo).log10()
        } else {
            v
        }
    }

    /// The value at a coordinate.
    fn value(self, x: f64) -> f64 {
        if self.log {
            10f64.powf(x)
        } else {
            x
        }
    }

    /// Labelled values: 1, 2, 5 × 10ⁿ on a log axis, a round step on a linear one.
    fn ticks(self) -> Vec<f64> {
        if self.log {
            return log_ticks(self.lo, self.hi);
        }
        if self.hi <= self.lo {
            return vec![self.lo];
        }
        let step = nice_below((self.hi - self.lo) / 5.0);
        let first = (self.lo / step).ceil() as i64;
        let last = (self.hi / step).floor() as i64;
        (first..=last).map(|k| k as f64 * step).collect()
    }
}

/// A linear coordinate labelled at given values (plotters' own linear coordinate picks its
/// labels itself).
struct Ticked {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
}

impl Ranged for Ticked {
    type FormatOption = plotters::coord::ranged1d::DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let fraction = (value - self.lo) / (self.hi - self.lo);
        limit.0 + (f64::from(limit.1 - limit.0) * fraction + 1e-3).floor() as i32
    }

    fn key_points<Hint: plotters::coord::ranged1d::KeyPointHint>(&self, _: Hint) -> Vec<f64> {
        self.ticks.clone()
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

/// Cumulative distributions of `curves` on `axis`, `size` px, with a reference curve
/// (dashed black) when given. A value beyond the axis runs off the right edge.
fn cdf_svg(
    name: &str,
    x_desc: &str,
    curves: &[Curve],
    axis: Axis,
    size: (u32, u32),
    reference: Option<&dyn Fn(f64) -> f64>,
) -> Result<String, ReportError> {
    let mut svg = String::new();
    {
        let err = plot_error(name);
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(&err)?;
        let ticks: Vec<f64> = axis.ticks().into_iter().map(|v| axis.place(v)).collect();
        let (x0, x1) = (axis.place(axis.lo), axis.place(axis.hi));
        let mut chart = ChartBuilder::on(&root)
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(56)
            .build_cartesian_2d(
                Ticked {
                    lo: x0,
                    hi: x1,
                    ticks,
                },
                0.0..1.0,
            )
            .map_err(&err)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc("fraction of points at or below")
            .x_label_formatter(&|x| short(axis.value(*x)))
            .y_label_formatter(&|v| format!("{v:.1}"))
            .light_line_style(faint())
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 13))
            .draw()
            .map_err(&err)?;
        for c in curves {
            let mut sorted = c.values.clone();
            sorted.sort_by(f64::total_cmp);
            let n = sorted.len() as f64;
            let mut steps = vec![(x0, 0.0)];
            let mut below = 0.0;
            for (k, v) in sorted.iter().enumerate() {
                if *v > axis.hi {
                    break;
                }
                let x = axis.place(*v);
                steps.push((x, k as f64 / n));
                below = (k + 1) as f64 / n;
                steps.push((x, below));
            }
            steps.push((x1, below));
            chart
                .draw_series(LineSeries::new(steps, c.colour.stroke_width(2)))
                .map_err(&err)?;
        }
        if let Some(f) = reference {
            let points: Vec<(f64, f64)> = (0..=200)
                .map(|k| {
                    let x = x0 + (x1 - x0) * f64::from(k) / 200.0;
                    (x, f(axis.value(x)))
                })
                .collect();
            chart
                .draw_series(DashedLineSeries::new(points, 6, 4, FLOOR.stroke_width(1)))
                .map_err(&err)?;
        }
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

/// The legend of a distribution plot.
fn cdf_legend(curves: &[Curve], reference: Option<&str>) -> String {
    let mut entries: Vec<(String, RGBColor, Mark)> = curves
        .iter()
        .map(|c| (c.label.clone(), c.colour, Mark::Line))
        .collect();
    entries.extend(reference.map(|r| (r.to_string(), FLOOR, Mark::Dashed)));
    legend(&entries)
}

/// Points of one series of a scatter plot.
struct Scatter {
    label: String,
    colour: RGBColor,
    points: Vec<(f64, f64)>,
}

/// Residual norm against the point's distance from the robot base origin, on a log y
/// axis: the raw errors and the `best` methods, with the noise floor's mean; the plot and
/// its legend.
fn distance_svg(
    e: &Evaluation,
    best: &[&MethodResult],
    floor_mm: Option<f64>,
) -> Result<[String; 2], ReportError> {
    let distance: Vec<f64> = e.nominal_mm.iter().map(|p| norm(*p)).collect();
    let (lo, hi) = range(&distance);
    let pad = ((hi - lo) * 0.05).max(1.0);
    let series: Vec<Scatter> = std::iter::once(Scatter {
        label: "uncompensated".to_string(),
        colour: BEFORE,
        points: distance
            .iter()
            .zip(&e.measured_error_mm)
            .map(|(d, v)| (*d, norm(*v)))
            .collect(),
    })
    .chain(best.iter().map(|m| {
        Scatter {
            label: m.method.name().to_string(),
            colour: colour(m),
            points: residuals(e, m)
                .into_iter()
                .map(|(i, r)| (distance[i], norm(r)))
                .collect(),
        }
    }))
    .collect();
    let values: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .chain(floor_mm)
        .collect();
    let (y_lo, y_hi) = log_range(&values);
    let mut svg = String::new();
    let mut entries = Vec::new();
    {
        let err = plot_error("distance");
        let root = SVGBackend::with_string(&mut svg, (860, 440)).into_drawing_area();
        root.fill(&WHITE).map_err(&err)?;
        let mut chart = ChartBuilder::on(&root)
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(60)
            .build_cartesian_2d(
                (lo - pad)..(hi + pad),
                (y_lo..y_hi)
                    .log_scale()
                    .with_key_points(log_ticks(y_lo, y_hi)),
            )
            .map_err(&err)?;
        chart
            .configure_mesh()
            .x_desc("distance of the target from the base origin, mm (base frame)")
            .y_desc("position residual norm, mm (log scale)")
            .x_label_formatter(&|v| short(*v))
            .y_label_formatter(&|v| short(*v))
            .light_line_style(faint())
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14))
            .draw()
            .map_err(&err)?;
        let bins = distance_bins(distance.len());
        // Few points are drawn plainly; many, small and translucent, under their medians.
        let (radius, opacity) = if distance.len() <= 200 {
            (3, 0.9)
        } else {
            (2, 0.45)
        };
        for s in series {
            let style = s.colour.mix(opacity).filled();
            chart
                .draw_series(
                    s.points
                        .iter()
                        .map(move |(d, n)| Circle::new((*d, n.max(y_lo)), radius, style)),
                )
                .map_err(&err)?;
            let medians = binned_medians(&s.points, (lo, hi), bins);
            chart
                .draw_series(LineSeries::new(
                    medians.iter().map(|(d, n)| (*d, n.max(y_lo))),
                    s.colour.stroke_width(3),
                ))
                .map_err(&err)?;
            entries.push((s.label, s.colour, Mark::Line));
        }
        if let Some(f) = floor_mm {
            chart
                .draw_series(DashedLineSeries::new(
                    [(lo - pad, f), (hi + pad, f)],
                    6,
                    4,
                    FLOOR.stroke_width(1),
                ))
                .map_err(&err)?;
            entries.push((
                "noise floor (mean a perfect predictor leaves)".to_string(),
                FLOOR,
                Mark::Dashed,
            ));
        }
        root.present().map_err(&err)?;
    }
    Ok([svg, legend(&entries)])
}

/// How many distance bins the medians of the distance plot are taken over: about 15
/// points a bin, 3 to 10 bins.
fn distance_bins(points: usize) -> usize {
    (points / 15).clamp(3, 10)
}

/// The median of the y values of `points` in each of `bins` equal bins of x over
/// `(lo, hi)`, at the bin's centre; bins with fewer than 3 points are left out.
fn binned_medians(points: &[(f64, f64)], (lo, hi): (f64, f64), bins: usize) -> Vec<(f64, f64)> {
    let width = ((hi - lo) / bins as f64).max(f64::MIN_POSITIVE);
    let mut groups = vec![Vec::new(); bins];
    for (x, y) in points {
        let b = (((x - lo) / width).floor().max(0.0) as usize).min(bins - 1);
        groups[b].push(*y);
    }
    groups
        .iter()
        .enumerate()
        .filter(|(_, g)| g.len() >= 3)
        .map(|(b, g)| (lo + (b as f64 + 0.5) * width, quantile(g, 0.5)))
        .collect()
}

/// Smallest and largest of `values` ((0, 1) when empty).
fn range(values: &[f64]) -> (f64, f64) {
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    if lo.is_finite() {
        (lo, hi)
    } else {
        (0.0, 1.0)
    }
}

/// A log axis range covering the positive `values`, padded by a little on each side.
fn log_range(values: &[f64]) -> (f64, f64) {
    let positive: Vec<f64> = values.iter().copied().filter(|v| *v > 0.0).collect();
    let (lo, hi) = range(&positive);
    let lo = if lo > 0.0 { lo } else { 1e-3 };
    let hi = hi.max(lo * 10.0);
    (lo / 1.25, hi * 1.25)
}

/// The side of the square plotting area of a map panel, px.
const MAP_SIDE: u32 = 380;
const MAP_MARGIN: u32 = 10;
const MAP_X_LABELS: u32 = 40;
const MAP_Y_LABELS: u32 = 62;

/// A square panel in which one mm is as long across as up, over `points` (two base-frame
/// coordinates), with room below for a scale bar. Returns the ranges.
fn square_ranges(points: &[[f64; 2]]) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let xs: Vec<f64> = points.iter().map(|p| p[0]).collect();
    let ys: Vec<f64> = points.iter().map(|p| p[1]).collect();
    let (x0, x1) = range(&xs);
    let (y0, y1) = range(&ys);
    let side = (x1 - x0).max(y1 - y0).max(1.0) * 1.2;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    // A little lower, so that the scale bar finds room under the points.
    let cy = cy - side * 0.04;
    (
        (cx - side / 2.0)..(cx + side / 2.0),
        (cy - side / 2.0)..(cy + side / 2.0),
    )
}

fn map_area<'a>(svg: &'a mut String) -> DrawingArea<SVGBackend<'a>, Shift> {
    SVGBackend::with_string(
        svg,
        (
            MAP_SIDE + MAP_Y_LABELS + 2 * MAP_MARGIN,
            MAP_SIDE + MAP_X_LABELS + 2 * MAP_MARGIN,
        ),
    )
    .into_drawing_area()
}

/// Which two base-frame axes a map panel shows.
#[derive(Clone, Copy)]
enum View {
    /// x right, y up: from above.
    Top,
    /// x right, z up: from the side (−y).
    Side,
}

impl View {
    fn axes(self) -> (usize, usize) {
        match self {
            View::Top => (0, 1),
            View::Side => (0, 2),
        }
    }

    fn name(self) -> &'static str {
        match self {
            View::Top => "top view (x–y)",
            View::Side => "side view (x–z)",
        }
    }

    fn desc(self) -> (&'static str, &'static str) {
        match self {
            View::Top => ("x, mm (base frame)", "y, mm (base frame)"),
            View::Side => ("x, mm (base frame)", "z, mm (base frame)"),
        }
    }

    fn project(self, v: [f64; 3]) -> [f64; 2] {
        let (a, b) = self.axes();
        [v[a], v[b]]
    }
}

/// A map of the workspace projected on `view`: white, with axes in mm, equal scales.
fn map_chart<'a, 'b>(
    root: &'a DrawingArea<SVGBackend<'b>, plotters::coord::Shift>,
    view: View,
    xr: std::ops::Range<f64>,
    yr: std::ops::Range<f64>,
    err: &dyn Fn(DrawingAreaErrorKind<std::io::Error>) -> ReportError,
) -> Result<
    ChartContext<
        'a,
        SVGBackend<'b>,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    ReportError,
> {
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(root)
        .margin(MAP_MARGIN)
        .x_label_area_size(MAP_X_LABELS)
        .y_label_area_size(MAP_Y_LABELS)
        .build_cartesian_2d(xr, yr)
        .map_err(err)?;
    let (x_desc, y_desc) = view.desc();
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_labels(6)
        .y_labels(6)
        .x_label_formatter(&|v| short(*v))
        .y_label_formatter(&|v| short(*v))
        .light_line_style(faint())
        .label_style((FONT, 12))
        .axis_desc_style((FONT, 13))
        .draw()
        .map_err(err)?;
    Ok(chart)
}

/// At most this many arrows per panel: more hide each other.
const MAX_ARROWS: usize = 400;

/// Error vectors as arrows from their points, `scale` mm of arrow per mm of error, with a
/// scale bar of `bar_mm` mm of error.
fn arrows_svg(
    name: &str,
    view: View,
    points: &[[f64; 3]],
    vectors: &[[f64; 3]],
    c: RGBColor,
    (scale, bar_mm): (f64, f64),
) -> Result<String, ReportError> {
    let projected: Vec<[f64; 2]> = points.iter().map(|p| view.project(*p)).collect();
    let (xr, yr) = square_ranges(&projected);
    let side = xr.end - xr.start;
    let stride = points.len().div_ceil(MAX_ARROWS).max(1);
    let mut svg = String::new();
    {
        let err = plot_error(name);
        let root = map_area(&mut svg);
        let mut chart = map_chart(&root, view, xr.clone(), yr.clone(), &err)?;
        let style = c.stroke_width(1);
        let mut shapes = Vec::new();
        for (p, v) in projected
            .iter()
            .zip(vectors)
            .step_by(stride)
            .map(|(p, v)| (*p, view.project(*v)))
        {
            let tip = [p[0] + v[0] * scale, p[1] + v[1] * scale];
            let length = ((tip[0] - p[0]).powi(2) + (tip[1] - p[1]).powi(2)).sqrt();
            shapes.push(PathElement::new([(p[0], p[1]), (tip[0], tip[1])], style));
            if length > side * 0.004 {
                // Two barbs of a third of the arrow, at ±25°.
                let head = (length * 0.3).min(side * 0.02);
                let (dx, dy) = ((p[0] - tip[0]) / length, (p[1] - tip[1]) / length);
                for angle in [0.44_f64, -0.44] {
                    let (s, co) = angle.sin_cos();
                    let barb = (
                        tip[0] + head * (dx * co - dy * s),
                        tip[1] + head * (dx * s + dy * co),
                    );
                    shapes.push(PathElement::new([(tip[0], tip[1]), barb], style));
                }
            }
        }
        chart.draw_series(shapes).map_err(&err)?;
        // The scale bar, bottom left, on a white ground so that arrows do not hide it.
        let x0 = xr.start + side * 0.05;
        let y0 = yr.start + side * 0.04;
        let label = format!(
            "{} mm error = {} mm arrow",
            short(bar_mm),
            short(bar_mm * scale)
        );
        let px = side / f64::from(MAP_SIDE);
        let width = (bar_mm * scale).max(label.chars().count() as f64 * 5.8 * px);
        let ground = WHITE.mix(0.85).filled();
        chart
            .draw_series([Rectangle::new(
                [
                    (x0 - 5.0 * px, y0 - 6.0 * px),
                    (x0 + width + 5.0 * px, y0 + side * 0.045 + 4.0 * px),
                ],
                ground,
            )])
            .map_err(&err)?;
        let bar = BLACK.stroke_width(2);
        chart
            .draw_series([PathElement::new([(x0, y0), (x0 + bar_mm * scale, y0)], bar)])
            .map_err(&err)?;
        chart
            .draw_series([Text::new(
                label,
                (x0, y0 + side * 0.045),
                (FONT, 12).into_font(),
            )])
            .map_err(&err)?;
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

/// Training samples and evaluated points, projected on `view`.
fn locations_svg(e: &Evaluation, view: View) -> Result<String, ReportError> {
    let training: Vec<[f64; 2]> = e
        .training_nominal_mm
        .iter()
        .map(|p| view.project(*p))
        .collect();
    let evaluated: Vec<[f64; 2]> = e.nominal_mm.iter().map(|p| view.project(*p)).collect();
    let all: Vec<[f64; 2]> = training.iter().chain(&evaluated).copied().collect();
    let (xr, yr) = square_ranges(&all);
    let mut svg = String::new();
    {
        let err = plot_error("locations");
        let root = map_area(&mut svg);
        let mut chart = map_chart(&root, view, xr, yr, &err)?;
        // The evaluated points first: the samples, fewer and often on a lattice, on top.
        let ring = EVALUATED.stroke_width(1);
        chart
            .draw_series(
                evaluated
                    .iter()
                    .map(move |p| Circle::new((p[0], p[1]), 3, ring)),
            )
            .map_err(&err)?;
        let dot = TRAINING.filled();
        chart
            .draw_series(
                training
                    .iter()
                    .map(move |p| Circle::new((p[0], p[1]), 2, dot)),
            )
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
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>Compensation evaluation</title>\n<style>\
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
         </style>\n</head>\n<body>\n<h1>Compensation evaluation</h1>\n<p>{}</p>\n\
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

/// The figures table, with the noise floor row and line.
fn figures_section(page: &mut String, e: &Evaluation, orientation: bool) {
    let floor_mm = e.noise_floor.as_ref().and_then(|f| f.best_mean_mm);
    page.push_str("<h2>Figures</h2>\n<table><tr><th>method</th><th>predicted</th><th>missed</th><th>mean mm</th><th>RMS mm</th><th>p95 mm</th><th>max mm</th>");
    if floor_mm.is_some() {
        page.push_str("<th>mean ÷ floor</th>");
    }
    page.push_str("<th>± SE mm</th><th>against best mm</th>");
    if orientation {
        page.push_str("<th>mean mrad</th><th>RMS mrad</th><th>p95 mrad</th><th>max mrad</th>");
    }
    page.push_str("<th class=\"note\">notes</th></tr>\n");
    let stat_cells = |s: Option<&crate::baselines::ResidualStats>, ratio: bool| {
        let mut cells = match s {
            Some(s) => [s.mean_norm, s.rms_norm, s.p95_norm, s.max_norm].map(Some),
            None => [None; 4],
        }
        .map(cell)
        .map(|c| format!("<td>{c}</td>"))
        .concat();
        if let (Some(floor), true) = (floor_mm, ratio) {
            let r = s.map(|s| s.mean_norm / floor);
            let _ = write!(
                cells,
                "<td>{}</td>",
                r.map_or("—".to_string(), |r| format!("{r:.2}"))
            );
        }
        if ratio {
            let se = s.and_then(|s| s.mean_norm_standard_error);
            let _ = write!(cells, "<td>{}</td>", cell(se));
        }
        cells
    };
    // The paired difference from the best method, ± its standard error.
    let against = |method: Option<crate::Method>| -> String {
        let Some(c) = &e.comparison else {
            return "<td>—</td>".to_string();
        };
        if method == Some(c.reference) {
            return "<td>best</td>".to_string();
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
    };
    let _ = write!(
        page,
        "<tr><td>{}uncompensated</td><td>{}</td><td>0</td>{}",
        swatch(BEFORE),
        e.nominal_mm.len(),
        stat_cells(Some(&e.uncompensated_position_mm), true)
    );
    page.push_str(&against(None));
    if orientation {
        page.push_str(&stat_cells(
            e.uncompensated_orientation_mrad.as_ref(),
            false,
        ));
    }
    page.push_str("<td class=\"note\">the measured errors</td></tr>\n");
    for m in &e.methods {
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
            stat_cells(m.position_mm.as_ref(), true)
        );
        page.push_str(&against(Some(m.method)));
        if orientation {
            page.push_str(&stat_cells(m.orientation_mrad.as_ref(), false));
        }
        let _ = writeln!(page, "<td class=\"note\">{}</td></tr>", escape(&note));
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
    if let Some(f) = &e.noise_floor {
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
    if let Some(c) = &e.comparison {
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
    figure(
        page,
        &svgs,
        &format!(
            "Nominal positions of the {} training samples ({}dark grey dots) and the {} \
             evaluated points ({}blue rings), {} (left) and {} (right), base frame, equal \
             scales on both axes; evaluated points outside the cloud of samples are \
             extrapolation.{}",
            e.training_nominal_mm.len(),
            swatch(TRAINING),
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
        "<h2>Kinematic identification{}</h2>\n<p>{} parameters identified, {} held at \
         nominal, {} unidentifiable; condition number of the identified parameters' scaled \
         Jacobian {:.1}; position RMS over the training samples {:.4} mm before, {:.4} mm \
         after{}; {} iterations{}.</p>\n",
        if e.calibrations.len() > 1 {
            format!(", fold {} of {}", c.split + 1, e.calibrations.len())
        } else {
            String::new()
        },
        c.identified.len(),
        c.held,
        c.unidentifiable.len(),
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
        let (scale, unit) = if r.unit == "rad" {
            (1e3, "mrad")
        } else {
            (1.0, "mm")
        };
        let identified = r.status == "identified";
        let value = if identified {
            format!("{:+.4}", r.value * scale)
        } else {
            "0".to_string()
        };
        let se = r
            .standard_error
            .map_or("—".to_string(), |s| format!("{:.4}", s * scale));
        let ratio = match (identified, r.standard_error) {
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
