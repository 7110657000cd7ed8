//! Line charts ([`line_chart`]) and the figure they share with the
//! log–log scatter ([`LineFigure`]).

use plotters::coord::Shift;
use plotters::prelude::*;

use super::checks::{check_finite, no_data, skipped_detail, transform_points};
use super::frame::{
    Chart, Figure, Frame, Marker, PreparedSeries, cross_strokes, de, draw_legend, legend_size, save,
};
use super::ticks::AxisTicks;
use super::{Drawn, Failure, LegendPosition, LineChart, Output, PALETTE, PlotError, Series};

/// Draws a line chart to `out.png()` and `out.svg()`.
///
/// Series get colours from [`PALETTE`] and markers (circle, square,
/// triangle, diamond) in order; reference lines are dashed, in the legend;
/// failures are crosses in the series' colour (one legend entry "failed").
pub fn line_chart(spec: &LineChart, out: &Output) -> Result<Drawn, PlotError> {
    let fig = &spec.title;
    if spec.series.is_empty() {
        return Err(no_data(fig, "no series"));
    }
    let mut notes = Vec::new();
    let mut series = Vec::new();
    for (i, s) in spec.series.iter().enumerate() {
        series.push(prepare_series(spec, i, s, &mut notes)?);
    }
    let references = prepare_references(spec, &mut notes)?;
    let xs: Vec<f64> = (series.iter())
        .flat_map(|s| (s.points.iter().map(|p| p.0)).chain(s.failures.iter().map(|f| f.0)))
        .collect();
    let mut ys: Vec<f64> = (series.iter())
        .flat_map(|s| (s.points.iter().map(|p| p.1)).chain(s.failures.iter().filter_map(|f| f.1)))
        .collect();
    if xs.is_empty() || (ys.is_empty() && references.is_empty()) {
        return Err(no_data(fig, &skipped_detail(&notes)));
    }
    ys.extend(references.iter().map(|r| r.0));
    let figure = LineFigure {
        frame: Frame {
            title: spec.title.clone(),
            x_label: spec.x.label.clone(),
            y_label: spec.y.label.clone(),
            x: AxisTicks::new(fig, "x", &spec.x, &xs)?,
            y: AxisTicks::new(fig, "y", &spec.y, &ys)?,
            x_grid: true,
            y_grid: true,
        },
        series,
        references,
        legend: spec.legend,
        fit_lines: Vec::new(),
        join_points: true,
    };
    let files = save(&figure, out)?;
    Ok(Drawn { files, notes })
}

/// Series `i` of `spec` in plotting coordinates, with its colour and
/// marker; what a log axis cannot show is skipped and noted.
fn prepare_series(
    spec: &LineChart,
    i: usize,
    s: &Series,
    notes: &mut Vec<String>,
) -> Result<PreparedSeries, PlotError> {
    let fig = &spec.title;
    if s.points.is_empty() && s.failures.is_empty() {
        return Err(PlotError::EmptySeries {
            figure: fig.clone(),
            series: s.name.clone(),
        });
    }
    let (xs, ys) = (spec.x.scale, spec.y.scale);
    let points = transform_points(fig, &s.name, &s.points, xs, ys, notes)?;
    let mut failures = Vec::new();
    for (k, f) in s.failures.iter().enumerate() {
        if let Some(failure) = prepare_failure(spec, s, k, f, notes)? {
            failures.push(failure);
        }
    }
    Ok(PreparedSeries {
        name: s.name.clone(),
        colour: PALETTE[i % PALETTE.len()],
        marker: Marker::ALL[i % Marker::ALL.len()],
        points,
        failures,
        has_fit: false,
    })
}

/// Failure `k` of series `s` in plotting coordinates: skipped (and noted)
/// when its x cannot be shown; without y (the bottom edge) when its y
/// cannot.
fn prepare_failure(
    spec: &LineChart,
    s: &Series,
    k: usize,
    f: &Failure,
    notes: &mut Vec<String>,
) -> Result<Option<(f64, Option<f64>)>, PlotError> {
    let fig = &spec.title;
    check_finite(fig, || format!("series '{}' failure {k} x", s.name), f.x)?;
    let Some(x) = spec.x.scale.forward(f.x) else {
        notes.push(format!(
            "series '{}': failure marker at x = {} skipped (x ≤ 0 on a log axis)",
            s.name, f.x
        ));
        return Ok(None);
    };
    let Some(y) = f.y else {
        return Ok(Some((x, None)));
    };
    check_finite(fig, || format!("series '{}' failure {k} y", s.name), y)?;
    let t = spec.y.scale.forward(y);
    if t.is_none() {
        notes.push(format!(
            "series '{}': failure marker at y = {y} ≤ 0 on a log axis put on the bottom edge",
            s.name
        ));
    }
    Ok(Some((x, t)))
}

/// The reference lines of `spec` as `(y, label, colour)` in plotting
/// coordinates; those a log axis cannot show are skipped and noted.
fn prepare_references(
    spec: &LineChart,
    notes: &mut Vec<String>,
) -> Result<Vec<(f64, String, RGBColor)>, PlotError> {
    let mut references = Vec::new();
    for (i, r) in spec.reference_lines.iter().enumerate() {
        check_finite(&spec.title, || format!("reference line '{}'", r.label), r.y)?;
        match spec.y.scale.forward(r.y) {
            Some(y) => references.push((y, r.label.clone(), PALETTE[i % PALETTE.len()])),
            None => notes.push(format!(
                "reference line '{}' at y = {} skipped (≤ 0 on a log axis)",
                r.label, r.y
            )),
        }
    }
    Ok(references)
}

/// A line chart or a scatter with fits, in plotting coordinates.
pub(super) struct LineFigure {
    /// Axes and title.
    pub(super) frame: Frame,
    /// Data series.
    pub(super) series: Vec<PreparedSeries>,
    /// Reference lines `(y, label, colour)`.
    pub(super) references: Vec<(f64, String, RGBColor)>,
    /// Legend placement.
    pub(super) legend: LegendPosition,
    /// Fitted lines (two end points each) and colours.
    pub(super) fit_lines: Vec<(Vec<(f64, f64)>, RGBColor)>,
    /// Join points by lines (line chart) or not (scatter).
    pub(super) join_points: bool,
}

impl Figure for LineFigure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let mut chart = self.frame.build(root)?;
        self.draw_references(&mut chart)?;
        for (line, colour) in &self.fit_lines {
            let style = colour.mix(0.9).stroke_width(2);
            chart
                .draw_series(LineSeries::new(line.clone(), style))
                .map_err(de)?;
        }
        for s in &self.series {
            self.draw_series(&mut chart, s)?;
        }
        let any_failure = self.series.iter().any(|s| !s.failures.is_empty());
        if any_failure {
            draw_failure_entry(&mut chart)?;
        }
        self.draw_legend(&mut chart, any_failure)
    }
}

impl LineFigure {
    /// The y of failure markers without a value: just above the bottom edge.
    fn bottom(&self) -> f64 {
        self.frame.y.lo + 0.025 * (self.frame.y.hi - self.frame.y.lo)
    }

    /// Draws the reference lines, dashed across the plot, each with a
    /// legend entry.
    fn draw_references<'a, DB: DrawingBackend + 'a>(
        &self,
        chart: &mut Chart<'a, DB>,
    ) -> Result<(), String> {
        let (x0, x1) = (self.frame.x.lo, self.frame.x.hi);
        for (y, label, colour) in &self.references {
            let style = colour.stroke_width(2);
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(x0, *y), (x1, *y)],
                    10,
                    6,
                    style,
                ))
                .map_err(de)?
                .label(label.as_str())
                .legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (9, 0)], style)
                        + PathElement::new(vec![(14, 0), (22, 0)], style)
                });
        }
        Ok(())
    }

    /// Draws one series: its line (when points are joined), its markers
    /// with a legend entry, and its failures as crosses.
    fn draw_series<'a, DB: DrawingBackend + 'a>(
        &self,
        chart: &mut Chart<'a, DB>,
        s: &PreparedSeries,
    ) -> Result<(), String> {
        let (colour, marker) = (s.colour, s.marker);
        if self.join_points && s.points.len() > 1 {
            chart
                .draw_series(LineSeries::new(s.points.clone(), colour.stroke_width(2)))
                .map_err(de)?;
        }
        let legend_line = self.join_points || s.has_fit;
        chart
            .draw_series(
                s.points.iter().map(|&p| {
                    EmptyElement::at(p) + Polygon::new(marker.outline(5), colour.filled())
                }),
            )
            .map_err(de)?
            .label(s.name.as_str())
            .legend(move |(x, y)| {
                let line = if legend_line {
                    colour.stroke_width(2)
                } else {
                    TRANSPARENT.into()
                };
                let shifted: Vec<_> = (marker.outline(5).into_iter())
                    .map(|(a, b)| (a + 11, b))
                    .collect();
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (22, 0)], line)
                    + Polygon::new(shifted, colour.filled())
            });
        let style = colour.stroke_width(3);
        for &(fx, fy) in &s.failures {
            let [a, b] = cross_strokes(7);
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((fx, fy.unwrap_or(self.bottom())))
                        + PathElement::new(a, style)
                        + PathElement::new(b, style),
                ))
                .map_err(de)?;
        }
        Ok(())
    }

    /// Draws the legend where it covers the least of the lines, markers,
    /// fits and reference lines.
    fn draw_legend<'a, DB: DrawingBackend + 'a>(
        &self,
        chart: &mut Chart<'a, DB>,
        any_failure: bool,
    ) -> Result<(), String> {
        let (x0, x1) = (self.frame.x.lo, self.frame.x.hi);
        let bottom = self.bottom();
        let polylines: Vec<Vec<(f64, f64)>> = (self.series.iter())
            .map(|s| s.points.clone())
            .chain(self.fit_lines.iter().map(|(l, _)| l.clone()))
            .chain(
                self.series
                    .iter()
                    .flat_map(|s| (s.failures.iter()).map(|f| vec![(f.0, f.1.unwrap_or(bottom))])),
            )
            .chain(self.references.iter().map(|r| vec![(x0, r.0), (x1, r.0)]))
            .collect();
        let mut labels: Vec<&str> = self.references.iter().map(|r| r.1.as_str()).collect();
        labels.extend(self.series.iter().map(|s| s.name.as_str()));
        if any_failure {
            labels.push("failed");
        }
        let size = legend_size(chart, &labels)?;
        if let Some(corner) = self
            .frame
            .legend_corner(self.legend, &polylines, true, size)
        {
            draw_legend(chart, corner)?;
        }
        Ok(())
    }
}

/// A legend-only entry "failed" with a cross: an empty series carrying the
/// label.
fn draw_failure_entry<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
) -> Result<(), String> {
    let style = BLACK.mix(0.75).stroke_width(3);
    chart
        .draw_series(std::iter::empty::<EmptyElement<(f64, f64), DB>>())
        .map_err(de)?
        .label("failed")
        .legend(move |(x, y)| {
            let [a, b] = cross_strokes(6);
            let shift =
                |v: Vec<(i32, i32)>| v.into_iter().map(|(p, q)| (p + 11, q)).collect::<Vec<_>>();
            EmptyElement::at((x, y))
                + PathElement::new(shift(a), style)
                + PathElement::new(shift(b), style)
        });
    Ok(())
}
