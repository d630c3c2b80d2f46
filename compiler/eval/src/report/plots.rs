//! The report's plots: colours, axes and the SVG figures (plotters), apart from the page
//! that arranges them.

use plotters::coord::Shift;
use plotters::prelude::*;

use std::fmt::Write as _;

use super::{escape, ReportError};
use crate::{Evaluation, MethodResult};

/// One colour per method, in [`crate::Method::ALL`] order, then a table scored as built;
/// grey is "uncompensated".
pub(super) const COLOURS: [RGBColor; 12] = [
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
pub(super) const BEFORE: RGBColor = RGBColor(150, 150, 150);
/// Training samples on the map of the workspace.
pub(super) const TRAINING: RGBColor = RGBColor(60, 60, 60);
/// Evaluated points on the map of the workspace.
pub(super) const EVALUATED: RGBColor = RGBColor(31, 119, 180);
/// The noise floor's reference lines.
pub(super) const FLOOR: RGBColor = RGBColor(0, 0, 0);

pub(super) const FONT: &str = "sans-serif";

pub(super) fn colour(m: &MethodResult) -> RGBColor {
    let index = crate::Method::ALL
        .iter()
        .position(|x| *x == m.method)
        .unwrap_or(crate::Method::ALL.len());
    COLOURS[index % COLOURS.len()]
}

pub(super) fn css(c: RGBColor) -> String {
    format!("rgb({},{},{})", c.0, c.1, c.2)
}

pub(super) fn swatch(c: RGBColor) -> String {
    format!(
        "<span class=\"swatch\" style=\"background:{}\"></span>",
        css(c)
    )
}

/// How a legend entry is drawn.
#[derive(Clone, Copy)]
pub(super) enum Mark {
    Line,
    Dashed,
}

/// A legend in HTML beside a plot: label and mark per entry, in order.
pub(super) fn legend(entries: &[(String, RGBColor, Mark)]) -> String {
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

pub(super) fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Position residuals (mm, base frame) of a method at the points it predicted, with the
/// point index.
pub(super) fn residuals(e: &Evaluation, m: &MethodResult) -> Vec<(usize, [f64; 3])> {
    m.position_residuals(&e.measured_error_mm)
}

/// Orientation residual norms (mrad) of a method at the points where it predicted an
/// orientation, when orientation was measured.
pub(super) fn orientation_norms(e: &Evaluation, m: &MethodResult) -> Vec<f64> {
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
pub(super) fn ranked(e: &Evaluation) -> Vec<&MethodResult> {
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

pub(super) fn plot_error<E: std::fmt::Debug>(plot: &str) -> impl Fn(E) -> ReportError + '_ {
    move |e| ReportError::Plot {
        plot: plot.to_string(),
        message: format!("{e:?}"),
    }
}

/// A number with about three significant digits and no trailing zeros.
pub(super) fn short(x: f64) -> String {
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
pub(super) fn nice_below(x: f64) -> f64 {
    let decade = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|v| *v <= x * (1.0 + 1e-9))
        .unwrap_or(decade)
}

/// The value at quantile `q` of `values` (nearest rank), 0 when empty.
pub(super) fn quantile(values: &[f64], q: f64) -> f64 {
    let mut sorted: Vec<f64> = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    match sorted.len() {
        0 => 0.0,
        n => sorted[((q * n as f64).ceil() as usize).clamp(1, n) - 1],
    }
}

/// Labelled values of a log axis from `lo` to `hi`: 1, 2, 5 × 10ⁿ.
pub(super) fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let first = lo.log10().floor() as i32;
    let last = hi.log10().ceil() as i32;
    (first..=last)
        .flat_map(|n| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(n)))
        .filter(|v| *v >= lo && *v <= hi)
        .collect()
}

/// The error function, Abramowitz and Stegun 7.1.26 (absolute error below 1.5e-7).
pub(super) fn erf(x: f64) -> f64 {
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
pub(super) fn maxwell_cdf(r: f64, sigma: f64) -> f64 {
    let u = r / sigma;
    erf(u / std::f64::consts::SQRT_2)
        - (2.0 / std::f64::consts::PI).sqrt() * u * (-u * u / 2.0).exp()
}

/// One curve of a cumulative distribution plot.
pub(super) struct Curve {
    pub(super) label: String,
    pub(super) colour: RGBColor,
    pub(super) values: Vec<f64>,
}

/// The mesh lines between labelled ones: faint, so that the data stand out.
pub(super) fn faint() -> ShapeStyle {
    BLACK.mix(0.03).stroke_width(1)
}

/// The x axis of a distribution plot.
#[derive(Clone, Copy)]
pub(super) struct Axis {
    pub(super) lo: f64,
    pub(super) hi: f64,
    pub(super) log: bool,
}

impl Axis {
    /// Where a value lies on the plot's own (linear) coordinate.
    pub(super) fn place(self, v: f64) -> f64 {
        if self.log {
            v.max(self.lo).log10()
        } else {
            v
        }
    }

    /// The value at a coordinate.
    pub(super) fn value(self, x: f64) -> f64 {
        if self.log {
            10f64.powf(x)
        } else {
            x
        }
    }

    /// Labelled values: 1, 2, 5 × 10ⁿ on a log axis, a round step on a linear one.
    pub(super) fn ticks(self) -> Vec<f64> {
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
pub(super) struct Ticked {
    pub(super) lo: f64,
    pub(super) hi: f64,
    pub(super) ticks: Vec<f64>,
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
pub(super) fn cdf_svg(
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
pub(super) fn cdf_legend(curves: &[Curve], reference: Option<&str>) -> String {
    let mut entries: Vec<(String, RGBColor, Mark)> = curves
        .iter()
        .map(|c| (c.label.clone(), c.colour, Mark::Line))
        .collect();
    entries.extend(reference.map(|r| (r.to_string(), FLOOR, Mark::Dashed)));
    legend(&entries)
}

/// Points of one series of a scatter plot.
pub(super) struct Scatter {
    pub(super) label: String,
    pub(super) colour: RGBColor,
    pub(super) points: Vec<(f64, f64)>,
}

/// Residual norm against the point's distance from the robot base origin, on a log y
/// axis: the raw errors and the `best` methods, with the noise floor's mean; the plot and
/// its legend.
pub(super) fn distance_svg(
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
pub(super) fn distance_bins(points: usize) -> usize {
    (points / 15).clamp(3, 10)
}

/// The median of the y values of `points` in each of `bins` equal bins of x over
/// `(lo, hi)`, at the bin's centre; bins with fewer than 3 points are left out.
pub(super) fn binned_medians(
    points: &[(f64, f64)],
    (lo, hi): (f64, f64),
    bins: usize,
) -> Vec<(f64, f64)> {
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
pub(super) fn range(values: &[f64]) -> (f64, f64) {
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
pub(super) fn log_range(values: &[f64]) -> (f64, f64) {
    let positive: Vec<f64> = values.iter().copied().filter(|v| *v > 0.0).collect();
    let (lo, hi) = range(&positive);
    let lo = if lo > 0.0 { lo } else { 1e-3 };
    let hi = hi.max(lo * 10.0);
    (lo / 1.25, hi * 1.25)
}

/// The side of the square plotting area of a map panel, px.
pub(super) const MAP_SIDE: u32 = 380;
pub(super) const MAP_MARGIN: u32 = 10;
pub(super) const MAP_X_LABELS: u32 = 40;
pub(super) const MAP_Y_LABELS: u32 = 62;

/// A square panel in which one mm is as long across as up, over `points` (two base-frame
/// coordinates), with room below for a scale bar. Returns the ranges.
pub(super) fn square_ranges(points: &[[f64; 2]]) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
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

pub(super) fn map_area<'a>(svg: &'a mut String) -> DrawingArea<SVGBackend<'a>, Shift> {
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
pub(super) enum View {
    /// x right, y up: from above.
    Top,
    /// x right, z up: from the side (−y).
    Side,
}

impl View {
    pub(super) fn axes(self) -> (usize, usize) {
        match self {
            View::Top => (0, 1),
            View::Side => (0, 2),
        }
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            View::Top => "top view (x–y)",
            View::Side => "side view (x–z)",
        }
    }

    pub(super) fn desc(self) -> (&'static str, &'static str) {
        match self {
            View::Top => ("x, mm (base frame)", "y, mm (base frame)"),
            View::Side => ("x, mm (base frame)", "z, mm (base frame)"),
        }
    }

    pub(super) fn project(self, v: [f64; 3]) -> [f64; 2] {
        let (a, b) = self.axes();
        [v[a], v[b]]
    }
}

/// A map of the workspace projected on `view`: white, with axes in mm, equal scales.
pub(super) fn map_chart<'a, 'b>(
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
pub(super) const MAX_ARROWS: usize = 400;

/// Error vectors as arrows from their points, `scale` mm of arrow per mm of error, with a
/// scale bar of `bar_mm` mm of error.
pub(super) fn arrows_svg(
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
pub(super) fn locations_svg(e: &Evaluation, view: View) -> Result<String, ReportError> {
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
