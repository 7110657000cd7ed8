//! Log–log scatters with one fitted power law per series
//! ([`scatter_loglog_with_fits`]).

use plotters::prelude::*;

use super::checks::{no_data, skipped_detail, transform_points};
use super::fit::fit_power_law;
use super::frame::{Frame, Marker, PreparedSeries, save};
use super::line::LineFigure;
use super::ticks::AxisTicks;
use super::{Axis, Drawn, Output, PALETTE, PlotError, Scale, ScatterFits, Series};

/// Draws points on log–log axes with a least-squares power-law fit per
/// series (solid line over the series' x range, slope in the legend) to
/// `out.png()` and `out.svg()`. A series with fewer than two distinct
/// positive x is drawn without a fit, and a note says so.
pub fn scatter_loglog_with_fits(spec: &ScatterFits, out: &Output) -> Result<Drawn, PlotError> {
    let fig = &spec.title;
    if spec.series.is_empty() {
        return Err(no_data(fig, "no series"));
    }
    let mut notes = Vec::new();
    let mut series = Vec::new();
    let mut fit_lines = Vec::new();
    for (i, s) in spec.series.iter().enumerate() {
        let (prepared, fit_line) = prepare_series(fig, i, s, &mut notes)?;
        series.push(prepared);
        fit_lines.extend(fit_line);
    }
    let xs: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.0))
        .collect();
    let mut ys: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .collect();
    if xs.is_empty() {
        return Err(no_data(fig, &skipped_detail(&notes)));
    }
    ys.extend(fit_lines.iter().flat_map(|(l, _)| l.iter().map(|p| p.1)));
    let x_axis = Axis::log10(spec.x_label.clone());
    let y_axis = Axis::log10(spec.y_label.clone());
    let figure = LineFigure {
        frame: Frame {
            title: spec.title.clone(),
            x_label: spec.x_label.clone(),
            y_label: spec.y_label.clone(),
            x: AxisTicks::new(fig, "x", &x_axis, &xs)?,
            y: AxisTicks::new(fig, "y", &y_axis, &ys)?,
            x_grid: true,
            y_grid: true,
        },
        series,
        references: Vec::new(),
        legend: spec.legend,
        fit_lines,
        join_points: false,
    };
    let files = save(&figure, out)?;
    Ok(Drawn { files, notes })
}

/// Series `i` in log–log plotting coordinates with its fitted line (two
/// end points over the series' x range, and its colour), or a note saying
/// why it has none; its legend name carries the slope.
fn prepare_series(
    fig: &str,
    i: usize,
    s: &Series,
    notes: &mut Vec<String>,
) -> Result<(PreparedSeries, Option<FitLine>), PlotError> {
    if s.points.is_empty() {
        return Err(PlotError::EmptySeries {
            figure: fig.to_string(),
            series: s.name.clone(),
        });
    }
    let points = transform_points(fig, &s.name, &s.points, Scale::Log10, Scale::Log10, notes)?;
    let kept: Vec<(f64, f64)> = (points.iter())
        .map(|&(x, y)| (10f64.powf(x), 10f64.powf(y)))
        .collect();
    let colour = PALETTE[i % PALETTE.len()];
    let mut name = s.name.clone();
    let mut fit_line = None;
    match fit_power_law(&kept) {
        Ok(fit) => {
            let (lo, hi) = (points.iter()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.0), b.max(p.0))
            });
            let line = vec![
                (lo, fit.intercept + fit.slope * lo),
                (hi, fit.intercept + fit.slope * hi),
            ];
            fit_line = Some((line, colour));
            name = format!("{name} (slope {:.2})", fit.slope);
        }
        Err(e) => notes.push(format!("series '{}': no fit: {e}", s.name)),
    }
    let prepared = PreparedSeries {
        name,
        colour,
        marker: Marker::ALL[i % Marker::ALL.len()],
        points,
        failures: Vec::new(),
        has_fit: fit_line.is_some(),
    };
    Ok((prepared, fit_line))
}

/// A fitted line: its two end points and its colour.
type FitLine = (Vec<(f64, f64)>, RGBColor);
