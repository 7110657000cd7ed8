//! Stacked bar charts ([`stacked_bars`]): bars grow to the right, the
//! categories listed top to bottom, so that long category names stay
//! readable.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::checks::{check_finite, no_data};
use super::frame::{Chart, Figure, Frame, de, draw_legend, legend_size, save};
use super::ticks::{AxisTicks, scientific_label};
use super::{
    Drawn, FONT, LEGEND_SIZE, LegendPosition, Output, PALETTE, PlotError, StackedBars, TICK_SIZE,
};
use crate::harness::text;

/// Half the thickness of a bar, in category units.
const HALF: f64 = 0.32;

/// Draws a stacked bar chart to `out.png()` and `out.svg()`.
pub fn stacked_bars(spec: &StackedBars, out: &Output) -> Result<Drawn, PlotError> {
    let max_total = checked_max_total(spec)?;
    let mut headroom = if spec.total_suffix.is_some() {
        1.12
    } else {
        1.04
    };
    let mut legend = spec.legend;
    if legend == LegendPosition::Auto {
        legend = LegendPosition::UpperRight;
        headroom /= 1.0 - legend_fraction(spec, out)?;
    }
    let n = spec.categories.len();
    let names: Vec<String> = spec.categories.iter().map(|c| c.name.clone()).collect();
    let figure = BarsFigure {
        frame: Frame {
            title: spec.title.clone(),
            x_label: spec.value_label.clone(),
            y_label: String::new(),
            x: AxisTicks::linear_fixed(&spec.title, 0.0, max_total * headroom)?,
            y: AxisTicks::categories(&names),
            x_grid: true,
            y_grid: false,
        },
        segments: spec.segments.clone(),
        used: (0..spec.segments.len())
            .map(|s| spec.categories.iter().any(|c| c.values[s] > 0.0))
            .collect(),
        bars: (spec.categories.iter().enumerate())
            .map(|(i, c)| ((n - 1 - i) as f64, c.values.clone()))
            .collect(),
        total_suffix: spec.total_suffix.clone(),
        legend,
    };
    let files = save(&figure, out)?;
    Ok(Drawn {
        files,
        notes: Vec::new(),
    })
}

/// The largest bar total of `spec`, after checking that there are
/// categories and segments, that every category has one value per segment,
/// and that every value is finite and `≥ 0` with some value `> 0`.
fn checked_max_total(spec: &StackedBars) -> Result<f64, PlotError> {
    let fig = &spec.title;
    if spec.categories.is_empty() {
        return Err(no_data(fig, "no categories"));
    }
    if spec.segments.is_empty() {
        return Err(no_data(fig, "no segment names"));
    }
    let mut max_total: f64 = 0.0;
    for c in &spec.categories {
        if c.values.len() != spec.segments.len() {
            return Err(PlotError::LengthMismatch {
                figure: fig.clone(),
                category: c.name.clone(),
                expected: spec.segments.len(),
                got: c.values.len(),
            });
        }
        for (seg, &v) in spec.segments.iter().zip(&c.values) {
            check_finite(fig, || format!("category '{}' segment '{seg}'", c.name), v)?;
            if v < 0.0 {
                return Err(PlotError::Negative {
                    figure: fig.clone(),
                    what: format!("category '{}' segment '{seg}'", c.name),
                    value: v,
                });
            }
        }
        max_total = max_total.max(c.values.iter().sum());
    }
    if max_total <= 0.0 {
        return Err(no_data(fig, "every value is zero"));
    }
    Ok(max_total)
}

/// The widest of `labels` at `size` pixels.
fn widest(mut labels: impl Iterator<Item = impl AsRef<str>>, size: f64) -> Result<f64, PlotError> {
    labels.try_fold(0.0f64, |w, label| {
        let width =
            text::text_width(label.as_ref(), size).map_err(|e| PlotError::Font(e.to_string()))?;
        Ok(w.max(width))
    })
}

/// The fraction of the value axis that a legend in the upper right corner
/// takes (estimated from the legend box and the plotting area), so that
/// room reserved for it keeps every bar from running under it.
fn legend_fraction(spec: &StackedBars, out: &Output) -> Result<f64, PlotError> {
    let label_w = widest(spec.segments.iter(), LEGEND_SIZE)?;
    let category_w = widest(spec.categories.iter().map(|c| &c.name), TICK_SIZE)?;
    let legend_extent = label_w + 34.0 + 40.0;
    let plot_extent = out.width as f64 - category_w - 70.0;
    Ok((legend_extent / plot_extent.max(1.0)).clamp(0.0, 0.6))
}

/// A stacked bar chart in plotting coordinates.
pub(super) struct BarsFigure {
    /// Axes and title.
    pub(super) frame: Frame,
    /// Segment names.
    pub(super) segments: Vec<String>,
    /// Whether a segment is non-zero somewhere (legend entry).
    pub(super) used: Vec<bool>,
    /// `(position on the category axis, values)` per bar.
    pub(super) bars: Vec<(f64, Vec<f64>)>,
    /// Unit suffix of printed totals, if any.
    pub(super) total_suffix: Option<String>,
    /// Legend placement.
    pub(super) legend: LegendPosition,
}

impl Figure for BarsFigure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let mut chart = self.frame.build(root)?;
        for s in 0..self.segments.len() {
            self.draw_segment(&mut chart, s)?;
        }
        if let Some(suffix) = &self.total_suffix {
            self.draw_totals(&mut chart, suffix)?;
        }
        self.draw_legend(&mut chart)
    }
}

impl BarsFigure {
    /// Draws segment `s` of every bar (a white outline between segments)
    /// and gives it a legend entry if it is used.
    fn draw_segment<DB: DrawingBackend>(
        &self,
        chart: &mut Chart<'_, DB>,
        s: usize,
    ) -> Result<(), String> {
        let colour = PALETTE[s % PALETTE.len()];
        let rects: Vec<_> = self
            .bars
            .iter()
            .filter(|(_, values)| values[s] > 0.0)
            .flat_map(|(c, values)| {
                let base: f64 = values[..s].iter().sum();
                let corners = [(base, c - HALF), (base + values[s], c + HALF)];
                [
                    Rectangle::new(corners, colour.filled()),
                    Rectangle::new(corners, WHITE.stroke_width(1)),
                ]
            })
            .collect();
        let series = chart.draw_series(rects).map_err(de)?;
        if self.used[s] {
            series
                .label(self.segments[s].as_str())
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 6), (x + 16, y + 6)], colour.filled())
                });
        }
        Ok(())
    }

    /// Prints each bar's total right of its end, with `suffix`.
    fn draw_totals<DB: DrawingBackend>(
        &self,
        chart: &mut Chart<'_, DB>,
        suffix: &str,
    ) -> Result<(), String> {
        let style = (FONT, TICK_SIZE)
            .into_font()
            .color(&BLACK)
            .pos(Pos::new(HPos::Left, VPos::Center));
        for (c, values) in &self.bars {
            let total: f64 = values.iter().sum();
            let text = format!("{}{suffix}", plain_total(total));
            let elem = EmptyElement::at((total, *c)) + Text::new(text, (6, 0), style.clone());
            chart.draw_series(std::iter::once(elem)).map_err(de)?;
        }
        Ok(())
    }

    /// Draws the legend of the used segments where it covers the fewest
    /// bars (samples along each bar's length and across its thickness).
    fn draw_legend<'a, DB: DrawingBackend + 'a>(
        &self,
        chart: &mut Chart<'a, DB>,
    ) -> Result<(), String> {
        let mut points = Vec::new();
        for (c, values) in &self.bars {
            let total: f64 = values.iter().sum();
            for k in 0..=10 {
                let v = total * k as f64 / 10.0;
                points.extend([(v, *c), (v, c - HALF), (v, c + HALF)]);
            }
        }
        let labels: Vec<&str> = (self.segments.iter().zip(&self.used))
            .filter(|(_, used)| **used)
            .map(|(s, _)| s.as_str())
            .collect();
        let size = legend_size(chart, &labels)?;
        if let Some(corner) = self
            .frame
            .legend_corner(self.legend, &[points], false, size)
        {
            draw_legend(chart, corner)?;
        }
        Ok(())
    }
}

/// A total printed at a bar's end: three significant digits.
fn plain_total(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !(1e-3..1e6).contains(&v.abs()) {
        return scientific_label(v);
    }
    let digits = (2.0 - v.abs().log10().floor()).max(0.0) as usize;
    format!("{v:.digits$}")
}
