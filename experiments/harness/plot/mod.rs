//! Typed plotting helpers over `plotters`: every figure is drawn once, by
//! code generic over the drawing backend, and written twice — as
//! `STEM.png` (bitmap) and `STEM.svg` (vector).
//!
//! Three figure kinds:
//! - [`line_chart`]: named series of `(x, y)` points, linear or log10 axes,
//!   horizontal reference lines, failure markers (×), legend;
//! - [`stacked_bars`]: categories, each a stack of named segments (a
//!   precompute-time breakdown), one colour per segment name;
//! - [`scatter_loglog_with_fits`]: points on log–log axes with a fitted power
//!   law per series, its slope in the legend (the fit is [`fit_power_law`]).
//!
//! Bad data never panics. The rules, applied before anything is drawn:
//! - a NaN or infinite coordinate is an error ([`PlotError::NonFinite`]);
//! - a series with no point (and, for line charts, no failure marker) is an
//!   error ([`PlotError::EmptySeries`]), and so is a figure without series;
//! - a point with a coordinate `≤ 0` on a log axis cannot be drawn: it is
//!   *skipped*, and every skip is said in [`Drawn::notes`]; a figure left
//!   with nothing drawable is an error ([`PlotError::NoData`]).
//!
//! Text is DejaVu Sans, embedded (crate `dejavu`) and registered under the
//! family name `"sans-serif"` by [`ensure_fonts`], so the SVG files name a
//! family every viewer has; PNG text is drawn by [`crate::harness::text`].

// Toolkit for the experiments: some items are used only by experiments that
// are still to be written (and by the tests).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::prelude::*;
use plotters::style::FontStyle;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::harness::text::GoodText;

/// Font family name under which DejaVu Sans is registered.
pub const FONT: &str = "sans-serif";

/// Colour-blind-safe palette (Okabe & Ito), in the order series and
/// segments receive colours; yellow last (weak on white).
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),   // blue
    RGBColor(213, 94, 0),    // vermillion
    RGBColor(0, 158, 115),   // bluish green
    RGBColor(204, 121, 167), // reddish purple
    RGBColor(230, 159, 0),   // orange
    RGBColor(86, 180, 233),  // sky blue
    RGBColor(0, 0, 0),       // black
    RGBColor(240, 228, 66),  // yellow
];

// Reference lines take the palette's colours in order (dashed), so that
// the reference line of series `i` (the same mesh) has that series' colour
// and no two of up to eight reference lines share one.

/// Font sizes (pixels) of the figures.
const TITLE_SIZE: f64 = 24.0;
/// Axis description font size.
const AXIS_DESC_SIZE: f64 = 19.0;
/// Tick label font size.
const TICK_SIZE: f64 = 16.0;
/// Legend font size.
const LEGEND_SIZE: f64 = 16.0;

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Nothing drawable is left (no series, or every point skipped).
    #[error("figure '{figure}': nothing to plot ({detail})")]
    NoData {
        /// Title of the figure.
        figure: String,
        /// What was missing or skipped.
        detail: String,
    },
    /// A series (or category) without any data.
    #[error("figure '{figure}': series '{series}' has no data")]
    EmptySeries {
        /// Title of the figure.
        figure: String,
        /// Name of the empty series or category.
        series: String,
    },
    /// A NaN or infinite value.
    #[error("figure '{figure}': {what} is not finite ({value})")]
    NonFinite {
        /// Title of the figure.
        figure: String,
        /// Which value: series, index and coordinate.
        what: String,
        /// The value.
        value: f64,
    },
    /// A negative bar segment.
    #[error("figure '{figure}': {what} = {value} is negative (stacked segments must be ≥ 0)")]
    Negative {
        /// Title of the figure.
        figure: String,
        /// Category and segment.
        what: String,
        /// The value.
        value: f64,
    },
    /// A category with a number of values different from the segments'.
    #[error(
        "figure '{figure}': category '{category}' has {got} values for {expected} segment names"
    )]
    LengthMismatch {
        /// Title of the figure.
        figure: String,
        /// The category.
        category: String,
        /// Number of segment names.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
    /// An explicit axis range that cannot be used.
    #[error("figure '{figure}': {axis} range ({lo}, {hi}) is invalid: {reason}")]
    InvalidRange {
        /// Title of the figure.
        figure: String,
        /// `"x"`, `"y"` or `"value"`.
        axis: &'static str,
        /// Lower end.
        lo: f64,
        /// Upper end.
        hi: f64,
        /// Why.
        reason: &'static str,
    },
    /// An output size of zero or above [`MAX_SIDE`] pixels.
    #[error("image size {width}×{height} is invalid (each side in 1..={MAX_SIDE})")]
    BadSize {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// A power-law fit that could not be computed.
    #[error("fit of series '{series}': {source}")]
    Fit {
        /// Name of the series.
        series: String,
        /// Why.
        #[source]
        source: FitError,
    },
    /// The embedded font could not be registered.
    #[error("font: {0}")]
    Font(String),
    /// The output directory could not be created.
    #[error("cannot create directory {path}: {source}")]
    Io {
        /// The directory.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The drawing backend failed (writing the file, drawing text, ...).
    #[error("drawing {path}: {message}")]
    Backend {
        /// The file being drawn.
        path: PathBuf,
        /// The backend's message.
        message: String,
    },
}

/// Why [`fit_power_law`] failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// Fewer than two points.
    #[error("needs at least 2 points, got {got}")]
    TooFewPoints {
        /// Number of points given.
        got: usize,
    },
    /// A coordinate that is not finite and positive.
    #[error("point {index} ({x}, {y}) is not finite and positive")]
    NotPositive {
        /// Index of the point.
        index: usize,
        /// Its x.
        x: f64,
        /// Its y.
        y: f64,
    },
    /// All x equal: the slope is undefined.
    #[error("all x are equal: the slope is undefined")]
    ConstantX,
}

/// Largest accepted image side, in pixels.
pub const MAX_SIDE: u32 = 16_384;

/// Registers DejaVu Sans (regular, bold, oblique) under [`FONT`]; idempotent
/// and cheap after the first call. Every drawing function calls it.
pub fn ensure_fonts() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            let faces = [
                (FontStyle::Normal, dejavu::sans::regular()),
                (FontStyle::Bold, dejavu::sans::bold()),
                (FontStyle::Italic, dejavu::sans::oblique()),
                (FontStyle::Oblique, dejavu::sans::oblique()),
            ];
            for (style, bytes) in faces {
                plotters::style::register_font(FONT, style, bytes).map_err(|_| {
                    format!(
                        "embedded DejaVu Sans ({}) is not a valid font",
                        style.as_str()
                    )
                })?;
            }
            Ok(())
        })
        .clone()
        .map_err(PlotError::Font)
}

/// Where a figure goes: `STEM.png` and `STEM.svg`, both `width × height`
/// pixels (the SVG's user units). Missing parent directories are created.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// Path without extension, e.g. `results/fig7_precompute`.
    pub stem: PathBuf,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Output {
    /// `stem` at the default size, 960 × 640.
    pub fn new(stem: impl Into<PathBuf>) -> Output {
        Output {
            stem: stem.into(),
            width: 960,
            height: 640,
        }
    }

    /// The same output at another size.
    pub fn with_size(mut self, width: u32, height: u32) -> Output {
        self.width = width;
        self.height = height;
        self
    }

    /// `STEM.png`.
    pub fn png(&self) -> PathBuf {
        with_extension(&self.stem, "png")
    }

    /// `STEM.svg`.
    pub fn svg(&self) -> PathBuf {
        with_extension(&self.stem, "svg")
    }
}

/// `stem` + `.ext` (appended, so a dot inside the stem is kept).
fn with_extension(stem: &Path, ext: &str) -> PathBuf {
    let mut s = stem.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

/// What a drawing function wrote, and what it had to leave out.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Drawn {
    /// The files written (PNG, then SVG).
    pub files: Vec<PathBuf>,
    /// Human-readable notes on skipped data (e.g. non-positive values on a
    /// log axis) and fits that could not be computed; empty if all was drawn.
    pub notes: Vec<String>,
}

/// Scale of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Linear.
    #[default]
    Linear,
    /// Base-10 logarithmic; values `≤ 0` are skipped (see the module docs).
    Log10,
}

impl Scale {
    /// The plotting coordinate of a data value: itself, or its log10
    /// (`None` for a value `≤ 0` on a log axis).
    fn forward(self, v: f64) -> Option<f64> {
        match self {
            Scale::Linear => Some(v),
            Scale::Log10 => (v > 0.0).then(|| v.log10()),
        }
    }
}

/// An axis: description, scale and optional fixed range (data units).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Axis {
    /// Axis description, e.g. `"soft-constraint weight w"`.
    pub label: String,
    /// Linear or log10.
    pub scale: Scale,
    /// Fixed `(lo, hi)` in data units; `None` fits the data.
    pub range: Option<(f64, f64)>,
}

impl Axis {
    /// A linear axis fitted to the data.
    pub fn linear(label: impl Into<String>) -> Axis {
        Axis {
            label: label.into(),
            scale: Scale::Linear,
            range: None,
        }
    }

    /// A log10 axis fitted to the data.
    pub fn log10(label: impl Into<String>) -> Axis {
        Axis {
            label: label.into(),
            scale: Scale::Log10,
            range: None,
        }
    }

    /// The same axis with a fixed range (data units).
    pub fn with_range(mut self, lo: f64, hi: f64) -> Axis {
        self.range = Some((lo, hi));
        self
    }
}

/// Where the legend goes, inside the plotting area.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LegendPosition {
    /// The corner (or edge middle) covering the least data; for stacked
    /// bars, the upper right corner with room reserved for it.
    #[default]
    Auto,
    /// Upper left corner.
    UpperLeft,
    /// Upper right corner.
    UpperRight,
    /// Lower left corner.
    LowerLeft,
    /// Lower right corner.
    LowerRight,
    /// No legend.
    Hidden,
}

/// A point where a series failed (e.g. the solver failed at that weight):
/// drawn as a cross in the series' colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Failure {
    /// Where along x.
    pub x: f64,
    /// At which y; `None` puts the cross on the bottom edge of the plot.
    pub y: Option<f64>,
}

/// A named series of `(x, y)` points.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Legend name.
    pub name: String,
    /// Points, drawn in the given order (joined by lines in a line chart).
    pub points: Vec<(f64, f64)>,
    /// Where the series failed (line charts only).
    pub failures: Vec<Failure>,
}

impl Series {
    /// A series without failures.
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
            failures: Vec::new(),
        }
    }

    /// The same series with failure markers.
    pub fn with_failures(mut self, failures: Vec<Failure>) -> Series {
        self.failures = failures;
        self
    }
}

/// A labelled horizontal line across the plot (e.g. the error of the
/// null-space method, against which penalty weights are compared).
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceLine {
    /// Its y, in data units.
    pub y: f64,
    /// Legend label.
    pub label: String,
}

/// A line chart (see [`line_chart`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LineChart {
    /// Title above the plot (may be empty).
    pub title: String,
    /// Horizontal axis.
    pub x: Axis,
    /// Vertical axis.
    pub y: Axis,
    /// The series; colours and markers follow their order.
    pub series: Vec<Series>,
    /// Horizontal reference lines (dashed).
    pub reference_lines: Vec<ReferenceLine>,
    /// Legend placement.
    pub legend: LegendPosition,
}

/// Bar direction of a [`StackedBars`] chart.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Orientation {
    /// Bars grow to the right, categories listed top to bottom (long
    /// category names stay readable).
    #[default]
    Horizontal,
    /// Bars grow upwards, categories left to right.
    Vertical,
}

/// One bar: a category and one value per segment name.
#[derive(Debug, Clone, PartialEq)]
pub struct Category {
    /// Label, e.g. `"bunny / hard+soft"`.
    pub name: String,
    /// `values[i]` belongs to `StackedBars::segments[i]`; `≥ 0`.
    pub values: Vec<f64>,
}

/// A stacked bar chart (see [`stacked_bars`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StackedBars {
    /// Title above the plot.
    pub title: String,
    /// Description of the value axis, e.g. `"time (s)"`.
    pub value_label: String,
    /// Segment names, bottom (or left) of the stack first. Segment `i`
    /// always gets `PALETTE[i % 8]`: pass the same list to every figure
    /// (zeros allowed) and a phase keeps its colour across figures.
    /// Segments that are zero in every category are left out of the legend.
    pub segments: Vec<String>,
    /// The bars, top to bottom (horizontal) or left to right (vertical).
    pub categories: Vec<Category>,
    /// Bar direction.
    pub orientation: Orientation,
    /// Print each bar's total at its end, formatted with this unit suffix
    /// (e.g. `Some(" s")`); `None` prints nothing.
    pub total_suffix: Option<String>,
    /// Legend placement; `Auto` puts it in the upper right corner and
    /// extends the value axis so that no bar runs under it.
    pub legend: LegendPosition,
}

/// A log–log scatter with one fitted power law per series (see
/// [`scatter_loglog_with_fits`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScatterFits {
    /// Title above the plot.
    pub title: String,
    /// Description of x (always log10).
    pub x_label: String,
    /// Description of y (always log10).
    pub y_label: String,
    /// The series (failures are ignored).
    pub series: Vec<Series>,
    /// Legend placement.
    pub legend: LegendPosition,
}

/// A least-squares fit `log10 y = intercept + slope · log10 x`, i.e.
/// `y = 10^intercept · x^slope`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerFit {
    /// The exponent.
    pub slope: f64,
    /// log10 of the coefficient.
    pub intercept: f64,
    /// Coefficient of determination of the fit in log–log space (1 when all
    /// points are on the line, or when all y are equal).
    pub r_squared: f64,
    /// Number of points fitted.
    pub n: usize,
}

impl PowerFit {
    /// The fitted `y` at `x` (`x > 0`).
    pub fn eval(&self, x: f64) -> f64 {
        10f64.powf(self.intercept + self.slope * x.log10())
    }
}

/// Least-squares fit of `log10 y` on `log10 x` (a power law `y = c·x^k`).
/// Every coordinate must be finite and `> 0`; at least two distinct x.
pub fn fit_power_law(points: &[(f64, f64)]) -> Result<PowerFit, FitError> {
    if points.len() < 2 {
        return Err(FitError::TooFewPoints { got: points.len() });
    }
    let mut logs = Vec::with_capacity(points.len());
    for (index, &(x, y)) in points.iter().enumerate() {
        if !(x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0) {
            return Err(FitError::NotPositive { index, x, y });
        }
        logs.push((x.log10(), y.log10()));
    }
    let n = logs.len() as f64;
    let mx = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let my = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let syy: f64 = logs.iter().map(|p| (p.1 - my).powi(2)).sum();
    // Relative test: x spread below rounding of the mean is no spread.
    if sxx <= (f64::EPSILON * (1.0 + mx.abs())).powi(2) * n {
        return Err(FitError::ConstantX);
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let ss_res: f64 = logs
        .iter()
        .map(|p| (p.1 - intercept - slope * p.0).powi(2))
        .sum();
    let r_squared = if syy > 0.0 {
        (1.0 - ss_res / syy).clamp(0.0, 1.0)
    } else {
        1.0
    };
    Ok(PowerFit {
        slope,
        intercept,
        r_squared,
        n: logs.len(),
    })
}

// ---------------------------------------------------------------------------
// Public drawing functions.

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

/// Draws a stacked bar chart to `out.png()` and `out.svg()`.
pub fn stacked_bars(spec: &StackedBars, out: &Output) -> Result<Drawn, PlotError> {
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
    let value_axis = Axis {
        label: spec.value_label.clone(),
        scale: Scale::Linear,
        range: None,
    };
    // Bars start at 0; leave room for the totals printed at the bar ends.
    let mut headroom = if spec.total_suffix.is_some() {
        1.12
    } else {
        1.04
    };
    let mut legend = spec.legend;
    if legend == LegendPosition::Auto {
        // Upper right, in room reserved along the value axis so that no bar
        // runs under it: estimate the legend box and the plotting area.
        legend = LegendPosition::UpperRight;
        let mut label_w: f64 = 0.0;
        for name in &spec.segments {
            label_w = label_w.max(
                crate::harness::text::text_width(name, LEGEND_SIZE)
                    .map_err(|e| PlotError::Font(e.to_string()))?,
            );
        }
        let mut category_w: f64 = 0.0;
        for c in &spec.categories {
            category_w = category_w.max(
                crate::harness::text::text_width(&c.name, TICK_SIZE)
                    .map_err(|e| PlotError::Font(e.to_string()))?,
            );
        }
        let entries = spec.segments.len() as f64;
        let (legend_extent, plot_extent) = match spec.orientation {
            Orientation::Horizontal => {
                (label_w + 34.0 + 40.0, out.width as f64 - category_w - 70.0)
            }
            Orientation::Vertical => (
                entries * (LEGEND_SIZE * 1.2 + 6.0) + 40.0,
                out.height as f64 - 150.0,
            ),
        };
        let fraction = (legend_extent / plot_extent.max(1.0)).clamp(0.0, 0.6);
        headroom /= 1.0 - fraction;
    }
    let value_ticks = AxisTicks::linear_fixed(fig, 0.0, max_total * headroom)?;
    let n = spec.categories.len();
    let names: Vec<String> = spec.categories.iter().map(|c| c.name.clone()).collect();
    let cat_ticks = AxisTicks::categories(&names, spec.orientation == Orientation::Horizontal);
    let (x, y, x_label, y_label, x_grid, y_grid) = match spec.orientation {
        Orientation::Horizontal => (
            value_ticks,
            cat_ticks,
            value_axis.label,
            String::new(),
            true,
            false,
        ),
        Orientation::Vertical => (
            cat_ticks,
            value_ticks,
            String::new(),
            value_axis.label,
            false,
            true,
        ),
    };
    let used: Vec<bool> = (0..spec.segments.len())
        .map(|s| spec.categories.iter().any(|c| c.values[s] > 0.0))
        .collect();
    let figure = BarsFigure {
        frame: Frame {
            title: spec.title.clone(),
            x_label,
            y_label,
            x,
            y,
            x_grid,
            y_grid,
        },
        segments: spec.segments.clone(),
        used,
        bars: spec
            .categories
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let pos = if spec.orientation == Orientation::Horizontal {
                    (n - 1 - i) as f64
                } else {
                    i as f64
                };
                (pos, c.values.clone())
            })
            .collect(),
        orientation: spec.orientation,
        total_suffix: spec.total_suffix.clone(),
        legend,
    };
    let files = save(&figure, out)?;
    Ok(Drawn {
        files,
        notes: Vec::new(),
    })
}

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
        if s.points.is_empty() {
            return Err(PlotError::EmptySeries {
                figure: fig.clone(),
                series: s.name.clone(),
            });
        }
        let points = transform_points(
            fig,
            &s.name,
            &s.points,
            Scale::Log10,
            Scale::Log10,
            &mut notes,
        )?;
        let kept: Vec<(f64, f64)> = points
            .iter()
            .map(|&(x, y)| (10f64.powf(x), 10f64.powf(y)))
            .collect();
        let colour = PALETTE[i % PALETTE.len()];
        let mut name = s.name.clone();
        let mut has_fit = false;
        match fit_power_law(&kept) {
            Ok(fit) => {
                let (lo, hi) = points
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                        (a.min(p.0), b.max(p.0))
                    });
                let line = vec![
                    (lo, fit.intercept + fit.slope * lo),
                    (hi, fit.intercept + fit.slope * hi),
                ];
                fit_lines.push((line, colour));
                name = format!("{name} (slope {:.2})", fit.slope);
                has_fit = true;
            }
            Err(e) => notes.push(format!("series '{}': no fit: {e}", s.name)),
        }
        series.push(PreparedSeries {
            name,
            colour,
            marker: Marker::ALL[i % Marker::ALL.len()],
            points,
            failures: Vec::new(),
            has_fit,
        });
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

// ---------------------------------------------------------------------------
// Validation helpers.

/// A [`PlotError::NoData`].
fn no_data(figure: &str, detail: &str) -> PlotError {
    PlotError::NoData {
        figure: figure.to_string(),
        detail: detail.to_string(),
    }
}

/// The notes, or a generic phrase, as the detail of a [`PlotError::NoData`].
fn skipped_detail(notes: &[String]) -> String {
    if notes.is_empty() {
        "no drawable point".into()
    } else {
        format!("no drawable point: {}", notes.join("; "))
    }
}

/// Errors with [`PlotError::NonFinite`] unless `v` is finite.
fn check_finite(figure: &str, what: impl FnOnce() -> String, v: f64) -> Result<(), PlotError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(PlotError::NonFinite {
            figure: figure.to_string(),
            what: what(),
            value: v,
        })
    }
}

/// Checks a series' points and maps them to plotting coordinates, skipping
/// (and noting) those that a log axis cannot show.
fn transform_points(
    figure: &str,
    name: &str,
    points: &[(f64, f64)],
    xs: Scale,
    ys: Scale,
    notes: &mut Vec<String>,
) -> Result<Vec<(f64, f64)>, PlotError> {
    let mut out = Vec::with_capacity(points.len());
    let mut skipped = Vec::new();
    for (i, &(x, y)) in points.iter().enumerate() {
        check_finite(figure, || format!("series '{name}' point {i} x"), x)?;
        check_finite(figure, || format!("series '{name}' point {i} y"), y)?;
        match (xs.forward(x), ys.forward(y)) {
            (Some(tx), Some(ty)) => out.push((tx, ty)),
            _ => skipped.push(format!("({x}, {y})")),
        }
    }
    if !skipped.is_empty() {
        const SHOWN: usize = 4;
        let more = if skipped.len() > SHOWN {
            format!(" and {} more", skipped.len() - SHOWN)
        } else {
            String::new()
        };
        notes.push(format!(
            "series '{name}': {} point(s) with a coordinate ≤ 0 on a log axis skipped: {}{more}",
            skipped.len(),
            skipped[..skipped.len().min(SHOWN)].join(", ")
        ));
    }
    Ok(out)
}

// ---------------------------------------------------------------------------
// Ticks and labels.

/// An axis in plotting coordinates (log10 of the data on log axes): range,
/// labelled major ticks and unlabelled minor grid lines.
#[derive(Debug, Clone, PartialEq)]
struct AxisTicks {
    /// Lower end.
    lo: f64,
    /// Upper end.
    hi: f64,
    /// Major ticks and their labels.
    majors: Vec<(f64, String)>,
    /// Minor grid lines.
    minors: Vec<f64>,
}

impl AxisTicks {
    /// Ticks for `axis`, fitted to `values` (plotting coordinates) unless the
    /// axis has a fixed range.
    fn new(
        figure: &str,
        name: &'static str,
        axis: &Axis,
        values: &[f64],
    ) -> Result<AxisTicks, PlotError> {
        let (lo, hi) = match axis.range {
            Some((lo, hi)) => {
                let bad = |reason| PlotError::InvalidRange {
                    figure: figure.to_string(),
                    axis: name,
                    lo,
                    hi,
                    reason,
                };
                if !(lo.is_finite() && hi.is_finite()) {
                    return Err(bad("not finite"));
                }
                if lo >= hi {
                    return Err(bad("lo ≥ hi"));
                }
                match axis.scale {
                    Scale::Linear => (lo, hi),
                    Scale::Log10 => {
                        if lo <= 0.0 {
                            return Err(bad("a log axis needs lo > 0"));
                        }
                        (lo.log10(), hi.log10())
                    }
                }
            }
            None => {
                let (mut lo, mut hi) = values
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                        (a.min(v), b.max(v))
                    });
                if !(lo.is_finite() && hi.is_finite()) {
                    lo = 0.0;
                    hi = 1.0;
                }
                if hi - lo <= 1e-12 * (1.0 + lo.abs().max(hi.abs())) {
                    let half = match axis.scale {
                        Scale::Log10 => 0.5,
                        Scale::Linear => (0.1 * lo.abs()).max(0.5),
                    };
                    lo -= half;
                    hi += half;
                }
                let pad = 0.05 * (hi - lo);
                (lo - pad, hi + pad)
            }
        };
        Ok(match axis.scale {
            Scale::Linear => AxisTicks::linear(lo, hi),
            Scale::Log10 => AxisTicks::log(lo, hi),
        })
    }

    /// Linear ticks over `[lo, hi]` (checked).
    fn linear_fixed(figure: &str, lo: f64, hi: f64) -> Result<AxisTicks, PlotError> {
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(PlotError::InvalidRange {
                figure: figure.to_string(),
                axis: "value",
                lo,
                hi,
                reason: "not finite or empty",
            });
        }
        Ok(AxisTicks::linear(lo, hi))
    }

    /// Ticks at 1–2–5 multiples of a power of ten, about six of them.
    fn linear(lo: f64, hi: f64) -> AxisTicks {
        // hi/6 − lo/6 stays finite even when hi − lo overflows.
        let step = nice_step(hi / 6.0 - lo / 6.0);
        let first = (lo / step).ceil() as i64;
        let last = (hi / step).floor() as i64;
        if last.saturating_sub(first) > 100 {
            // Only when rounding defeats the step (spans near f64::MAX):
            // label the ends.
            return AxisTicks {
                lo,
                hi,
                majors: vec![(lo, scientific_label(lo)), (hi, scientific_label(hi))],
                minors: Vec::new(),
            };
        }
        let digits = (-step.log10().floor()).max(0.0) as usize;
        let max_abs = lo.abs().max(hi.abs());
        let scientific = max_abs >= 1e5 || step < 1e-3;
        let majors = (first..=last)
            .map(|k| {
                let v = k as f64 * step;
                let label = if k == 0 {
                    "0".to_string()
                } else if scientific {
                    scientific_label(v)
                } else {
                    format!("{v:.digits$}")
                };
                (v, label)
            })
            .collect();
        let mantissa = step / 10f64.powf(step.log10().floor());
        let minor_step = if (mantissa - 2.0).abs() < 1e-6 {
            step / 4.0
        } else {
            step / 5.0
        };
        let minors = ((lo / minor_step).ceil() as i64..=(hi / minor_step).floor() as i64)
            .take(1000)
            .map(|k| k as f64 * minor_step)
            .collect();
        AxisTicks {
            lo,
            hi,
            majors,
            minors,
        }
    }

    /// Ticks of a log10 axis over `[lo, hi]` (exponents): decades, labelled
    /// `10ᵏ` (plain numbers between 0.01 and 10⁴), at most ~8 of them; below
    /// two decades in range, 1–2–5 multiples, labelled as plain numbers.
    fn log(lo: f64, hi: f64) -> AxisTicks {
        let first = lo.ceil() as i64;
        let last = hi.floor() as i64;
        let decades = (last - first + 1).max(0);
        let inside = |t: f64| t >= lo - 1e-12 && t <= hi + 1e-12;
        if decades >= 2 {
            let every = [1i64, 2, 3, 4, 5, 10, 20, 50, 100]
                .into_iter()
                .find(|&e| decades / e <= 8)
                .unwrap_or(decades);
            let plain = first >= -2 && last <= 4;
            let mut majors = Vec::new();
            let mut minors = Vec::new();
            for k in first - 1..=last {
                let t = k as f64;
                if (first..=last).contains(&k) {
                    if k.rem_euclid(every) == 0 {
                        let label = if plain {
                            plain_label(10f64.powi(k as i32))
                        } else {
                            format!("10{}", superscript(k))
                        };
                        majors.push((t, label));
                    } else {
                        minors.push(t);
                    }
                }
                if every == 1 && decades <= 10 {
                    for m in 2..=9 {
                        let tm = t + (m as f64).log10();
                        if inside(tm) {
                            minors.push(tm);
                        }
                    }
                }
            }
            return AxisTicks {
                lo,
                hi,
                majors,
                minors,
            };
        }
        // Less than two decades: 1-2-5 (or 1..9) multiples.
        for mantissas in [
            &[1.0, 2.0, 5.0][..],
            &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0][..],
        ] {
            let mut majors = Vec::new();
            for k in (lo.floor() as i64)..=(hi.ceil() as i64) {
                for &m in mantissas {
                    let v = m * 10f64.powi(k as i32);
                    let t = v.log10();
                    if inside(t) {
                        majors.push((t, plain_label(v)));
                    }
                }
            }
            if majors.len() >= 3 || mantissas.len() == 9 {
                if majors.len() < 2 {
                    // Less than a factor 2 of range: linear-looking ticks.
                    let lin = AxisTicks::linear(10f64.powf(lo), 10f64.powf(hi));
                    majors = lin
                        .majors
                        .into_iter()
                        .filter(|(v, _)| *v > 0.0)
                        .map(|(v, l)| (v.log10(), l))
                        .collect();
                }
                return AxisTicks {
                    lo,
                    hi,
                    majors,
                    minors: Vec::new(),
                };
            }
        }
        AxisTicks {
            lo,
            hi,
            majors: Vec::new(),
            minors: Vec::new(),
        }
    }

    /// A category axis: positions `0..n`, labels given (reversed when the
    /// first category is to be on top).
    fn categories(names: &[String], top_down: bool) -> AxisTicks {
        let n = names.len();
        let majors = names
            .iter()
            .enumerate()
            .map(|(i, name)| {
                let pos = if top_down { n - 1 - i } else { i };
                (pos as f64, name.clone())
            })
            .collect();
        AxisTicks {
            lo: -0.6,
            hi: n as f64 - 0.4,
            majors,
            minors: Vec::new(),
        }
    }

    /// The label of the major tick at `v`, or an empty string.
    fn label(&self, v: f64) -> String {
        let tol = 1e-9 * (1.0 + (self.hi - self.lo).abs());
        self.majors
            .iter()
            .find(|(t, _)| (t - v).abs() <= tol)
            .map(|(_, l)| l.clone())
            .unwrap_or_default()
    }

    /// The plotters coordinate of this axis.
    fn coord(&self) -> TickCoord {
        TickCoord {
            lo: self.lo,
            hi: self.hi,
            majors: self.majors.iter().map(|m| m.0).collect(),
            minors: self.minors.clone(),
        }
    }
}

/// A linear plotters coordinate with given major (labelled) and minor
/// (light grid) key points.
#[derive(Debug, Clone)]
struct TickCoord {
    /// Lower end.
    lo: f64,
    /// Upper end.
    hi: f64,
    /// Major key points.
    majors: Vec<f64>,
    /// Minor key points.
    minors: Vec<f64>,
}

impl Ranged for TickCoord {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let t = (value - self.lo) / (self.hi - self.lo);
        let pixels = (limit.1 - limit.0) as f64 * t;
        // Clamp far-away values so that the i32 conversion stays exact.
        limit.0 + (pixels + 1e-3).floor().clamp(-1e6, 1e6) as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.minors.clone()
        } else {
            self.majors.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

/// The smallest of 1, 2, 5, 10 × 10ᵏ not below `raw`.
fn nice_step(raw: f64) -> f64 {
    if !(raw.is_finite() && raw > 0.0) {
        return 1.0;
    }
    let mag = 10f64.powf(raw.log10().floor());
    let m = raw / mag;
    let nice = if m <= 1.0 + 1e-9 {
        1.0
    } else if m <= 2.0 + 1e-9 {
        2.0
    } else if m <= 5.0 + 1e-9 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

/// `k` in Unicode superscript digits (`-3` → `⁻³`).
fn superscript(k: i64) -> String {
    k.to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect()
}

/// `v` as `m×10ᵏ` (or `10ᵏ` when `m = 1`), `m` with up to two decimals.
fn scientific_label(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let k = v.abs().log10().floor() as i64;
    let m = v / 10f64.powi(k as i32);
    let m_text = format!("{m:.2}");
    let m_text = m_text.trim_end_matches('0').trim_end_matches('.');
    match m_text {
        "1" => format!("10{}", superscript(k)),
        "-1" => format!("−10{}", superscript(k)),
        _ => format!("{m_text}×10{}", superscript(k)),
    }
}

/// A positive number in plain notation with at most three significant
/// digits and no trailing zeros (`0.002`, `50`, `20000`).
fn plain_label(v: f64) -> String {
    if !(1e-4..1e6).contains(&v.abs()) {
        return scientific_label(v);
    }
    let digits = (2.0 - v.abs().log10().floor()).max(0.0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

// ---------------------------------------------------------------------------
// Drawing, generic over the backend.

/// A figure that can be drawn on any backend.
trait Figure {
    /// Draws the whole figure on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String>;
}

/// Draws `figure` to `out.png()` then `out.svg()`.
fn save(figure: &impl Figure, out: &Output) -> Result<Vec<PathBuf>, PlotError> {
    if out.width == 0 || out.height == 0 || out.width > MAX_SIDE || out.height > MAX_SIDE {
        return Err(PlotError::BadSize {
            width: out.width,
            height: out.height,
        });
    }
    ensure_fonts()?;
    if let Some(parent) = out.stem.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|source| PlotError::Io {
            path: parent.to_path_buf(),
            source,
        })?;
    }
    let size = (out.width, out.height);
    let png = out.png();
    let backend_error = |path: &Path, message: String| PlotError::Backend {
        path: path.to_path_buf(),
        message,
    };
    {
        let root = GoodText::new(BitMapBackend::new(&png, size)).into_drawing_area();
        figure.draw(&root).map_err(|m| backend_error(&png, m))?;
        root.present()
            .map_err(|e| backend_error(&png, e.to_string()))?;
    }
    let svg = out.svg();
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        figure.draw(&root).map_err(|m| backend_error(&svg, m))?;
        root.present()
            .map_err(|e| backend_error(&svg, e.to_string()))?;
    }
    Ok(vec![png, svg])
}

/// Stringifies a drawing error.
fn de<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> String {
    e.to_string()
}

/// Point markers of successive series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Marker {
    /// Filled circle.
    Circle,
    /// Filled square.
    Square,
    /// Filled upward triangle.
    Triangle,
    /// Filled diamond.
    Diamond,
}

impl Marker {
    /// All markers, in the order series receive them.
    const ALL: [Marker; 4] = [
        Marker::Circle,
        Marker::Square,
        Marker::Triangle,
        Marker::Diamond,
    ];

    /// The marker's outline as pixel offsets from its centre, radius `r`.
    fn outline(self, r: i32) -> Vec<(i32, i32)> {
        let rf = r as f64;
        match self {
            Marker::Circle => (0..16)
                .map(|k| {
                    let a = k as f64 * std::f64::consts::TAU / 16.0;
                    ((rf * a.cos()).round() as i32, (rf * a.sin()).round() as i32)
                })
                .collect(),
            Marker::Square => {
                let s = (rf * 0.85).round() as i32;
                vec![(-s, -s), (s, -s), (s, s), (-s, s)]
            }
            Marker::Triangle => {
                let h = (rf * 1.15).round() as i32;
                vec![(0, -h), (h, (rf * 0.75) as i32), (-h, (rf * 0.75) as i32)]
            }
            Marker::Diamond => {
                let d = (rf * 1.2).round() as i32;
                vec![(0, -d), (d, 0), (0, d), (-d, 0)]
            }
        }
    }
}

/// The two strokes of a failure cross, centre-relative.
fn cross_strokes(r: i32) -> [Vec<(i32, i32)>; 2] {
    [vec![(-r, -r), (r, r)], vec![(-r, r), (r, -r)]]
}

/// A series ready to draw, in plotting coordinates.
#[derive(Debug, Clone)]
struct PreparedSeries {
    /// Legend name.
    name: String,
    /// Colour.
    colour: RGBColor,
    /// Marker shape.
    marker: Marker,
    /// Points.
    points: Vec<(f64, f64)>,
    /// Failure markers (`None`: bottom edge).
    failures: Vec<(f64, Option<f64>)>,
    /// Whether a fitted line is drawn in the series' colour (scatter).
    has_fit: bool,
}

/// Title, axis descriptions and ticks of a 2-D chart.
#[derive(Debug, Clone)]
struct Frame {
    /// Title.
    title: String,
    /// Description of x.
    x_label: String,
    /// Description of y.
    y_label: String,
    /// Horizontal axis.
    x: AxisTicks,
    /// Vertical axis.
    y: AxisTicks,
    /// Vertical grid lines at x ticks.
    x_grid: bool,
    /// Horizontal grid lines at y ticks.
    y_grid: bool,
}

/// The chart type every figure draws on.
type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<TickCoord, TickCoord>>;

impl Frame {
    /// Fills `root` white, lays out the chart (label areas sized to the
    /// measured tick labels) and draws axes, ticks, grid and descriptions.
    fn build<'a, DB: DrawingBackend>(
        &self,
        root: &'a DrawingArea<DB, Shift>,
    ) -> Result<Chart<'a, DB>, String> {
        root.fill(&WHITE).map_err(de)?;
        let tick_font = (FONT, TICK_SIZE).into_font();
        let desc_font = (FONT, AXIS_DESC_SIZE).into_font();
        let tick_style = TextStyle::from(tick_font.clone());
        let desc_style = TextStyle::from(desc_font.clone());
        let width_of = |labels: &[(f64, String)]| -> Result<u32, String> {
            let mut w = 0;
            for (_, l) in labels {
                let (lw, _) = root.estimate_text_size(l, &tick_style).map_err(de)?;
                w = w.max(lw);
            }
            Ok(w)
        };
        let (_, desc_h) = root.estimate_text_size("Ag", &desc_style).map_err(de)?;
        let (_, tick_h) = root.estimate_text_size("0g", &tick_style).map_err(de)?;
        let y_desc = if self.y_label.is_empty() {
            0
        } else {
            desc_h + 14
        };
        let x_desc = if self.x_label.is_empty() {
            0
        } else {
            desc_h + 12
        };
        let y_area = width_of(&self.y.majors)? + 18 + y_desc;
        let x_area = tick_h + 20 + x_desc;
        // Room on the right for the last x tick label, which is centred on
        // the plot's edge.
        let right =
            (width_of(&self.x.majors[self.x.majors.len().saturating_sub(1)..])? / 2 + 8).max(20);
        let mut builder = ChartBuilder::on(root);
        builder
            .margin_top(12)
            .margin_bottom(8)
            .margin_left(12)
            .margin_right(right)
            .x_label_area_size(x_area)
            .y_label_area_size(y_area);
        if !self.title.is_empty() {
            builder.caption(&self.title, (FONT, TITLE_SIZE).into_font());
        }
        let mut chart = builder
            .build_cartesian_2d(self.x.coord(), self.y.coord())
            .map_err(de)?;
        let x_fmt = |v: &f64| self.x.label(*v);
        let y_fmt = |v: &f64| self.y.label(*v);
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(self.x_label.as_str())
            .y_desc(self.y_label.as_str())
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .label_style(tick_font.clone())
            .axis_desc_style(desc_font.clone())
            .bold_line_style(BLACK.mix(0.13))
            .light_line_style(BLACK.mix(0.05))
            .axis_style(BLACK.mix(0.8))
            .set_all_tick_mark_size(5);
        if !self.x_grid {
            mesh.disable_x_mesh();
        }
        if !self.y_grid {
            mesh.disable_y_mesh();
        }
        mesh.draw().map_err(de)?;
        Ok(chart)
    }

    /// The legend position for `pos`, choosing for [`LegendPosition::Auto`]
    /// among the four corners and the four edge middles the place where a
    /// legend box of `size` (fractions of the plotting area) would cover
    /// the least of `polylines` (plot coordinates; points weigh 20, and with
    /// `join` each of 40 samples along a segment weighs 1). Ties go to the
    /// corners (upper right first).
    fn legend_corner(
        &self,
        pos: LegendPosition,
        polylines: &[Vec<(f64, f64)>],
        join: bool,
        size: (f64, f64),
    ) -> Option<SeriesLabelPosition> {
        match pos {
            LegendPosition::Hidden => None,
            LegendPosition::UpperLeft => Some(SeriesLabelPosition::UpperLeft),
            LegendPosition::UpperRight => Some(SeriesLabelPosition::UpperRight),
            LegendPosition::LowerLeft => Some(SeriesLabelPosition::LowerLeft),
            LegendPosition::LowerRight => Some(SeriesLabelPosition::LowerRight),
            LegendPosition::Auto => {
                let nx = |x: f64| (x - self.x.lo) / (self.x.hi - self.x.lo);
                let ny = |y: f64| (y - self.y.lo) / (self.y.hi - self.y.lo);
                // Candidate boxes: (position, u range, v range), corners
                // first (preferred on ties).
                let (bw, bh) = size;
                let (left, centre, right) =
                    ((0.0, bw), (0.5 - bw / 2.0, 0.5 + bw / 2.0), (1.0 - bw, 1.0));
                let (bottom, middle, top) =
                    ((0.0, bh), (0.5 - bh / 2.0, 0.5 + bh / 2.0), (1.0 - bh, 1.0));
                let candidates = [
                    (SeriesLabelPosition::UpperRight, right, top),
                    (SeriesLabelPosition::UpperLeft, left, top),
                    (SeriesLabelPosition::LowerRight, right, bottom),
                    (SeriesLabelPosition::LowerLeft, left, bottom),
                    (SeriesLabelPosition::UpperMiddle, centre, top),
                    (SeriesLabelPosition::LowerMiddle, centre, bottom),
                    (SeriesLabelPosition::MiddleRight, right, middle),
                    (SeriesLabelPosition::MiddleLeft, left, middle),
                ];
                // Cost: a data point or marker under the legend costs 20,
                // each sample along a line 1.
                let mut costs = [0usize; 8];
                let mut add = |x: f64, y: f64, cost: usize| {
                    let (u, v) = (nx(x), ny(y));
                    for (k, (_, us, vs)) in candidates.iter().enumerate() {
                        if u >= us.0 && u <= us.1 && v >= vs.0 && v <= vs.1 {
                            costs[k] += cost;
                        }
                    }
                };
                for line in polylines {
                    for p in line {
                        add(p.0, p.1, 20);
                    }
                    if join {
                        for w in line.windows(2) {
                            for k in 1..40 {
                                let t = k as f64 / 40.0;
                                add(
                                    w[0].0 + t * (w[1].0 - w[0].0),
                                    w[0].1 + t * (w[1].1 - w[0].1),
                                    1,
                                );
                            }
                        }
                    }
                }
                let best = (0..candidates.len())
                    .min_by_key(|&i| (costs[i], i))
                    .unwrap_or(0);
                Some(candidates[best].0.clone())
            }
        }
    }
}

/// The size of the legend box for `labels`, as fractions of the plotting
/// area of `chart` (with its margin, and a little slack).
fn legend_size<'a, DB: DrawingBackend + 'a>(
    chart: &Chart<'a, DB>,
    labels: &[&str],
) -> Result<(f64, f64), String> {
    let area = chart.plotting_area();
    let (pw, ph) = area.dim_in_pixel();
    let style = TextStyle::from((FONT, LEGEND_SIZE).into_font());
    let mut width = 0u32;
    let mut height = 0u32;
    for l in labels {
        let (w, h) = area.estimate_text_size(l, &style).map_err(de)?;
        width = width.max(w);
        height += h + 6;
    }
    let box_w = width as f64 + 34.0 + 30.0;
    let box_h = height as f64 + 20.0;
    Ok((box_w / pw.max(1) as f64, box_h / ph.max(1) as f64))
}

/// Draws the legend box of `chart` at `corner`.
fn draw_legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    corner: SeriesLabelPosition,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(corner)
        .margin(12)
        .legend_area_size(34)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK.mix(0.4))
        .label_font((FONT, LEGEND_SIZE).into_font())
        .draw()
        .map_err(de)
}

/// A line chart or a scatter with fits, in plotting coordinates.
struct LineFigure {
    /// Axes and title.
    frame: Frame,
    /// Data series.
    series: Vec<PreparedSeries>,
    /// Reference lines `(y, label, colour)`.
    references: Vec<(f64, String, RGBColor)>,
    /// Legend placement.
    legend: LegendPosition,
    /// Fitted lines (two end points each) and colours.
    fit_lines: Vec<(Vec<(f64, f64)>, RGBColor)>,
    /// Join points by lines (line chart) or not (scatter).
    join_points: bool,
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

/// A stacked bar chart in plotting coordinates.
struct BarsFigure {
    /// Axes and title.
    frame: Frame,
    /// Segment names.
    segments: Vec<String>,
    /// Whether a segment is non-zero somewhere (legend entry).
    used: Vec<bool>,
    /// `(position on the category axis, values)` per bar.
    bars: Vec<(f64, Vec<f64>)>,
    /// Bar direction.
    orientation: Orientation,
    /// Unit suffix of printed totals, if any.
    total_suffix: Option<String>,
    /// Legend placement.
    legend: LegendPosition,
}

impl Figure for BarsFigure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let mut chart = self.frame.build(root)?;
        let half = 0.32;
        let horizontal = self.orientation == Orientation::Horizontal;
        // (category position, value) → chart coordinates.
        let at = |c: f64, v: f64| if horizontal { (v, c) } else { (c, v) };
        for (s, name) in self.segments.iter().enumerate() {
            let colour = PALETTE[s % PALETTE.len()];
            let rects: Vec<_> = self
                .bars
                .iter()
                .filter(|(_, values)| values[s] > 0.0)
                .flat_map(|(c, values)| {
                    let base: f64 = values[..s].iter().sum();
                    let top = base + values[s];
                    [
                        Rectangle::new([at(c - half, base), at(c + half, top)], colour.filled()),
                        Rectangle::new(
                            [at(c - half, base), at(c + half, top)],
                            WHITE.stroke_width(1),
                        ),
                    ]
                })
                .collect();
            let series = chart.draw_series(rects).map_err(de)?;
            if self.used[s] {
                series.label(name.as_str()).legend(move |(x, y)| {
                    Rectangle::new([(x, y - 6), (x + 16, y + 6)], colour.filled())
                });
            }
        }
        if let Some(suffix) = &self.total_suffix {
            let font = (FONT, TICK_SIZE).into_font().color(&BLACK);
            let style = if horizontal {
                font.pos(Pos::new(HPos::Left, VPos::Center))
            } else {
                font.pos(Pos::new(HPos::Center, VPos::Bottom))
            };
            for (c, values) in &self.bars {
                let total: f64 = values.iter().sum();
                let text = format!("{}{suffix}", plain_total(total));
                let (x, y) = at(*c, total);
                let elem = EmptyElement::at((x, y))
                    + Text::new(
                        text,
                        if horizontal { (6, 0) } else { (0, -4) },
                        style.clone(),
                    );
                chart.draw_series(std::iter::once(elem)).map_err(de)?;
            }
        }
        let mut points = Vec::new();
        for (c, values) in &self.bars {
            let total: f64 = values.iter().sum();
            for k in 0..=10 {
                let v = total * k as f64 / 10.0;
                points.push(at(*c, v));
                points.push(at(c - half, v));
                points.push(at(c + half, v));
            }
        }
        let labels: Vec<&str> = self
            .segments
            .iter()
            .zip(&self.used)
            .filter(|(_, used)| **used)
            .map(|(s, _)| s.as_str())
            .collect();
        let size = legend_size(&chart, &labels)?;
        if let Some(corner) = self
            .frame
            .legend_corner(self.legend, &[points], false, size)
        {
            draw_legend(&mut chart, corner)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh directory under the system temp dir for this test, removed
    /// when dropped unless `LSE_KEEP_TEST_PLOTS` is set (to look at them).
    struct TmpDir(PathBuf);

    impl TmpDir {
        /// `name`'s file in the directory.
        fn join(&self, name: &str) -> PathBuf {
            self.0.join(name)
        }
    }

    impl Drop for TmpDir {
        fn drop(&mut self) {
            if std::env::var_os("LSE_KEEP_TEST_PLOTS").is_none() {
                let _ = std::fs::remove_dir_all(&self.0);
            }
        }
    }

    /// A [`TmpDir`] for the test `name`.
    fn tmp(name: &str) -> TmpDir {
        let dir = std::env::temp_dir().join(format!("lse-plot-test-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TmpDir(dir)
    }

    #[test]
    fn fit_recovers_a_known_power_law() {
        let pts: Vec<(f64, f64)> = [10.0, 30.0, 100.0, 1000.0, 5e4]
            .iter()
            .map(|&x: &f64| (x, 3.5 * x.powf(1.37)))
            .collect();
        let fit = fit_power_law(&pts).unwrap();
        assert!((fit.slope - 1.37).abs() < 1e-12, "{fit:?}");
        assert!((fit.intercept - 3.5f64.log10()).abs() < 1e-12);
        assert!((fit.r_squared - 1.0).abs() < 1e-12);
        assert_eq!(fit.n, 5);
        assert!((fit.eval(200.0) / (3.5 * 200f64.powf(1.37)) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn fit_of_noisy_data_has_slope_near_truth() {
        // Alternating ±5 % noise around y = x².
        let pts: Vec<(f64, f64)> = (1..=40)
            .map(|i| {
                let x = i as f64 * 25.0;
                (x, x * x * if i % 2 == 0 { 1.05 } else { 0.95 })
            })
            .collect();
        let fit = fit_power_law(&pts).unwrap();
        assert!((fit.slope - 2.0).abs() < 0.02, "{fit:?}");
        assert!(fit.r_squared > 0.99 && fit.r_squared < 1.0);
    }

    #[test]
    fn fit_rejects_bad_input() {
        assert_eq!(
            fit_power_law(&[(1.0, 1.0)]),
            Err(FitError::TooFewPoints { got: 1 })
        );
        assert_eq!(
            fit_power_law(&[(1.0, 1.0), (0.0, 2.0)]),
            Err(FitError::NotPositive {
                index: 1,
                x: 0.0,
                y: 2.0
            })
        );
        assert!(matches!(
            fit_power_law(&[(1.0, 1.0), (2.0, f64::NAN)]),
            Err(FitError::NotPositive { index: 1, .. })
        ));
        assert_eq!(
            fit_power_law(&[(3.0, 1.0), (3.0, 2.0)]),
            Err(FitError::ConstantX)
        );
    }

    #[test]
    fn log_axis_skips_non_positive_values_and_says_so() {
        let dir = tmp("logskip");
        let spec = LineChart {
            title: "skip".into(),
            x: Axis::log10("w"),
            y: Axis::log10("error"),
            series: vec![Series::new(
                "a",
                vec![(1.0, 1.0), (10.0, 0.0), (-1.0, 5.0), (100.0, 1e-3)],
            )],
            ..LineChart::default()
        };
        let drawn = line_chart(&spec, &Output::new(dir.join("skip")).with_size(400, 300)).unwrap();
        assert_eq!(drawn.notes.len(), 1, "{:?}", drawn.notes);
        assert!(drawn.notes[0].contains("2 point(s)"), "{}", drawn.notes[0]);
        assert!(drawn.notes[0].contains("(10, 0)") && drawn.notes[0].contains("(-1, 5)"));
        for f in &drawn.files {
            assert!(std::fs::metadata(f).unwrap().len() > 100, "{f:?}");
        }
    }

    #[test]
    fn log_axis_with_only_non_positive_values_is_an_error() {
        let dir = tmp("lognone");
        let spec = LineChart {
            title: "none".into(),
            x: Axis::linear("w"),
            y: Axis::log10("error"),
            series: vec![Series::new("a", vec![(1.0, 0.0), (2.0, -1.0)])],
            ..LineChart::default()
        };
        let err = line_chart(&spec, &Output::new(dir.join("none"))).unwrap_err();
        match err {
            PlotError::NoData { detail, .. } => assert!(detail.contains("≤ 0"), "{detail}"),
            other => panic!("unexpected {other:?}"),
        }
        assert!(!dir.join("none.png").exists());
    }

    #[test]
    fn nan_empty_and_bad_ranges_are_errors() {
        let dir = tmp("errors");
        let out = Output::new(dir.join("e"));
        let mut spec = LineChart {
            title: "t".into(),
            series: vec![Series::new("a", vec![(1.0, f64::NAN)])],
            ..LineChart::default()
        };
        assert!(matches!(
            line_chart(&spec, &out),
            Err(PlotError::NonFinite { .. })
        ));
        spec.series = vec![Series::new("empty", vec![])];
        assert!(matches!(
            line_chart(&spec, &out),
            Err(PlotError::EmptySeries { .. })
        ));
        spec.series = vec![];
        assert!(matches!(
            line_chart(&spec, &out),
            Err(PlotError::NoData { .. })
        ));
        spec.series = vec![Series::new("a", vec![(1.0, 2.0), (2.0, 3.0)])];
        spec.y = Axis::log10("y").with_range(0.0, 10.0);
        assert!(matches!(
            line_chart(&spec, &out),
            Err(PlotError::InvalidRange { axis: "y", .. })
        ));
        assert!(matches!(
            line_chart(
                &LineChart {
                    y: Axis::linear("y"),
                    ..spec.clone()
                },
                &out.clone().with_size(0, 10)
            ),
            Err(PlotError::BadSize { .. })
        ));
        let bars = StackedBars {
            title: "b".into(),
            segments: vec!["qr".into(), "chol".into()],
            categories: vec![Category {
                name: "c".into(),
                values: vec![1.0],
            }],
            ..StackedBars::default()
        };
        assert!(matches!(
            stacked_bars(&bars, &out),
            Err(PlotError::LengthMismatch { .. })
        ));
        let negative = StackedBars {
            categories: vec![Category {
                name: "c".into(),
                values: vec![1.0, -0.5],
            }],
            ..bars
        };
        assert!(matches!(
            stacked_bars(&negative, &out),
            Err(PlotError::Negative { .. })
        ));
    }

    #[test]
    fn every_feature_draws_to_png_and_svg() {
        let dir = tmp("features");
        let line = LineChart {
            title: "Relative error against penalty weight".into(),
            x: Axis::log10("penalty weight w"),
            y: Axis::log10("relative error"),
            series: vec![
                Series::new(
                    "penalty, LLT",
                    vec![
                        (1.0, 0.3),
                        (1e2, 3e-3),
                        (1e4, 3e-5),
                        (1e6, 3e-7),
                        (1e8, 0.0),
                    ],
                )
                .with_failures(vec![Failure { x: 1e10, y: None }]),
                Series::new(
                    "penalty, QR",
                    vec![
                        (1.0, 0.3),
                        (1e2, 3e-3),
                        (1e4, 3e-5),
                        (1e6, 4e-7),
                        (1e8, 3e-9),
                    ],
                )
                .with_failures(vec![Failure {
                    x: 1e10,
                    y: Some(0.5),
                }]),
            ],
            reference_lines: vec![
                ReferenceLine {
                    y: 2e-15,
                    label: "null-space method".into(),
                },
                ReferenceLine {
                    y: -1.0,
                    label: "skipped".into(),
                },
            ],
            legend: LegendPosition::Auto,
        };
        let drawn = line_chart(&line, &Output::new(dir.join("line"))).unwrap();
        assert_eq!(drawn.notes.len(), 2, "{:?}", drawn.notes);
        let svg = std::fs::read_to_string(dir.join("line.svg")).unwrap();
        for text in [
            "null-space method",
            "penalty, LLT",
            "failed",
            "penalty weight w",
        ] {
            assert!(svg.contains(text), "{text} missing from the SVG");
        }
        let bars = StackedBars {
            title: "Breakdown".into(),
            value_label: "time (s)".into(),
            segments: ["set-up", "QR", "numeric"].map(String::from).to_vec(),
            categories: vec![
                Category {
                    name: "bunny / hard+soft".into(),
                    values: vec![0.2, 1.5, 0.7],
                },
                Category {
                    name: "bunny / soft only".into(),
                    values: vec![0.2, 0.0, 2.2],
                },
            ],
            orientation: Orientation::Vertical,
            total_suffix: Some(" s".into()),
            legend: LegendPosition::Auto,
        };
        let drawn = stacked_bars(&bars, &Output::new(dir.join("bars"))).unwrap();
        assert!(drawn.notes.is_empty());
        let svg = std::fs::read_to_string(dir.join("bars.svg")).unwrap();
        assert!(svg.contains("bunny / soft only") && svg.contains("2.40 s"));
        let scatter = ScatterFits {
            title: "Scaling".into(),
            x_label: "n".into(),
            y_label: "t".into(),
            series: vec![
                Series::new(
                    "n log n",
                    (1..6)
                        .map(|k| (10f64.powi(k), 10f64.powi(k) * k as f64))
                        .collect(),
                ),
                Series::new("single", vec![(100.0, 1.0), (-5.0, 1.0)]),
            ],
            legend: LegendPosition::UpperLeft,
        };
        let drawn = scatter_loglog_with_fits(&scatter, &Output::new(dir.join("scatter"))).unwrap();
        // One note for the skipped point, one for the missing fit.
        assert_eq!(drawn.notes.len(), 2, "{:?}", drawn.notes);
        let svg = std::fs::read_to_string(dir.join("scatter.svg")).unwrap();
        assert!(svg.contains("n log n (slope 1.1"), "slope in the legend");
    }

    #[test]
    fn log_ticks_are_decades_with_superscripts() {
        let t = AxisTicks::log(-6.2, 1.3);
        let labels: Vec<&str> = t.majors.iter().map(|m| m.1.as_str()).collect();
        assert_eq!(
            labels,
            ["10⁻⁶", "10⁻⁵", "10⁻⁴", "10⁻³", "10⁻²", "10⁻¹", "10⁰", "10¹"]
        );
        // Minor ticks at 2..9 × 10ᵏ inside the range.
        assert!(t.minors.iter().any(|&m| (m - 2f64.log10()).abs() < 1e-12));
        // Many decades: every other decade labelled, at most 8 labels.
        let wide = AxisTicks::log(-16.0, 2.0);
        assert!(wide.majors.len() <= 8, "{:?}", wide.majors);
        assert!(
            wide.majors
                .iter()
                .all(|m| (m.0.round() as i64) % 3 == 0 || (m.0.round() as i64) % 2 == 0)
        );
        // Less than two decades: plain 1-2-5 labels.
        let narrow = AxisTicks::log(0.05, 1.2);
        let labels: Vec<&str> = narrow.majors.iter().map(|m| m.1.as_str()).collect();
        assert_eq!(labels, ["2", "5", "10"]);
        // Plain decades near 1.
        let plain = AxisTicks::log(-2.0, 3.0);
        let labels: Vec<&str> = plain.majors.iter().map(|m| m.1.as_str()).collect();
        assert_eq!(labels, ["0.01", "0.1", "1", "10", "100", "1000"]);
    }

    #[test]
    fn linear_ticks_are_round() {
        let t = AxisTicks::linear(-0.03, 1.07);
        let labels: Vec<&str> = t.majors.iter().map(|m| m.1.as_str()).collect();
        assert_eq!(labels, ["0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
        let big = AxisTicks::linear(0.0, 1.6e6);
        assert_eq!(big.majors[1].1, "5×10⁵");
        // The whole f64 range: a few ticks, no endless loop.
        let huge = AxisTicks::linear(-f64::MAX, f64::MAX);
        assert!(
            huge.majors.len() >= 2 && huge.majors.len() <= 101,
            "{:?}",
            huge.majors
        );
    }
}
