//! Line charts ([`line_chart`]) and the figure they share with the
//! log–log scatter ([`LineFigure`]).

use super::*;

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
        if s.points.is_empty() && s.failures.is_empty() {
            return Err(PlotError::EmptySeries {
                figure: fig.clone(),
                series: s.name.clone(),
            });
        }
        let points = transform_points(
            fig,
            &s.name,
            &s.points,
            spec.x.scale,
            spec.y.scale,
            &mut notes,
        )?;
        let mut failures = Vec::new();
        for (k, f) in s.failures.iter().enumerate() {
            check_finite(fig, || format!("series '{}' failure {k} x", s.name), f.x)?;
            let Some(x) = spec.x.scale.forward(f.x) else {
                notes.push(format!(
                    "series '{}': failure marker at x = {} skipped (x ≤ 0 on a log axis)",
                    s.name, f.x
                ));
                continue;
            };
            let y = match f.y {
                None => None,
                Some(y) => {
                    check_finite(fig, || format!("series '{}' failure {k} y", s.name), y)?;
                    let t = spec.y.scale.forward(y);
                    if t.is_none() {
                        notes.push(format!(
                            "series '{}': failure marker at y = {y} ≤ 0 on a log axis put on the bottom edge",
                            s.name
                        ));
                    }
                    t
                }
            };
            failures.push((x, y));
        }
        series.push(PreparedSeries {
            name: s.name.clone(),
            colour: PALETTE[i % PALETTE.len()],
            marker: Marker::ALL[i % Marker::ALL.len()],
            points,
            failures,
            has_fit: false,
        });
    }
    let mut references = Vec::new();
    for (i, r) in spec.reference_lines.iter().enumerate() {
        check_finite(fig, || format!("reference line '{}'", r.label), r.y)?;
        match spec.y.scale.forward(r.y) {
            Some(y) => references.push((y, r.label.clone(), PALETTE[i % PALETTE.len()])),
            None => notes.push(format!(
                "reference line '{}' at y = {} skipped (≤ 0 on a log axis)",
                r.label, r.y
            )),
        }
    }
    let xs: Vec<f64> = series
        .iter()
        .flat_map(|s| {
            s.points
                .iter()
                .map(|p| p.0)
                .chain(s.failures.iter().map(|f| f.0))
        })
        .collect();
    let mut ys: Vec<f64> = series
        .iter()
        .flat_map(|s| {
            s.points
                .iter()
                .map(|p| p.1)
                .chain(s.failures.iter().filter_map(|f| f.1))
        })
        .collect();
    if xs.is_empty() || (ys.is_empty() && references.is_empty()) {
        return Err(no_data(fig, &skipped_detail(&notes)));
    }
    ys.extend(references.iter().map(|r| r.0));
    let x_ticks = AxisTicks::new(fig, "x", &spec.x, &xs)?;
    let y_ticks = AxisTicks::new(fig, "y", &spec.y, &ys)?;
    let figure = LineFigure {
        frame: Frame {
            title: spec.title.clone(),
            x_label: spec.x.label.clone(),
            y_label: spec.y.label.clone(),
            x: x_ticks,
            y: y_ticks,
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
        for (line, colour) in &self.fit_lines {
            chart
                .draw_series(LineSeries::new(
                    line.clone(),
                    colour.mix(0.9).stroke_width(2),
                ))
                .map_err(de)?;
        }
        let bottom = self.frame.y.lo + 0.025 * (self.frame.y.hi - self.frame.y.lo);
        let mut any_failure = false;
        for s in &self.series {
            let colour = s.colour;
            let marker = s.marker;
            if self.join_points && s.points.len() > 1 {
                chart
                    .draw_series(LineSeries::new(s.points.clone(), colour.stroke_width(2)))
                    .map_err(de)?;
            }
            let legend_line = self.join_points || s.has_fit;
            chart
                .draw_series(s.points.iter().map(|&p| {
                    EmptyElement::at(p) + Polygon::new(marker.outline(5), colour.filled())
                }))
                .map_err(de)?
                .label(s.name.as_str())
                .legend(move |(x, y)| {
                    let line = if legend_line {
                        colour.stroke_width(2)
                    } else {
                        TRANSPARENT.into()
                    };
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (22, 0)], line)
                        + Polygon::new(
                            marker
                                .outline(5)
                                .into_iter()
                                .map(|(a, b)| (a + 11, b))
                                .collect::<Vec<_>>(),
                            colour.filled(),
                        )
                });
            for &(fx, fy) in &s.failures {
                any_failure = true;
                let [a, b] = cross_strokes(7);
                let style = colour.stroke_width(3);
                chart
                    .draw_series(std::iter::once(
                        EmptyElement::at((fx, fy.unwrap_or(bottom)))
                            + PathElement::new(a, style)
                            + PathElement::new(b, style),
                    ))
                    .map_err(de)?;
            }
        }
        if any_failure {
            // A legend-only entry: an empty series carrying the label.
            let style = BLACK.mix(0.75).stroke_width(3);
            chart
                .draw_series(std::iter::empty::<EmptyElement<(f64, f64), DB>>())
                .map_err(de)?
                .label("failed")
                .legend(move |(x, y)| {
                    let [a, b] = cross_strokes(6);
                    let shift = |v: Vec<(i32, i32)>| {
                        v.into_iter().map(|(p, q)| (p + 11, q)).collect::<Vec<_>>()
                    };
                    EmptyElement::at((x, y))
                        + PathElement::new(shift(a), style)
                        + PathElement::new(shift(b), style)
                });
        }
        let polylines: Vec<Vec<(f64, f64)>> = self
            .series
            .iter()
            .map(|s| s.points.clone())
            .chain(self.fit_lines.iter().map(|(l, _)| l.clone()))
            .chain(self.series.iter().flat_map(|s| {
                s.failures
                    .iter()
                    .map(|f| vec![(f.0, f.1.unwrap_or(bottom))])
            }))
            .chain(self.references.iter().map(|r| vec![(x0, r.0), (x1, r.0)]))
            .collect();
        let mut labels: Vec<&str> = self.references.iter().map(|r| r.1.as_str()).collect();
        labels.extend(self.series.iter().map(|s| s.name.as_str()));
        if any_failure {
            labels.push("failed");
        }
        let size = legend_size(&chart, &labels)?;
        if let Some(corner) = self
            .frame
            .legend_corner(self.legend, &polylines, true, size)
        {
            draw_legend(&mut chart, corner)?;
        }
        Ok(())
    }
}
