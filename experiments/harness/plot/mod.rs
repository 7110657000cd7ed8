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

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crate::harness::text;
pub use crate::harness::text::FONT;

mod bars;
mod checks;
mod fit;
mod frame;
mod line;
mod scatter;
#[cfg(test)]
mod tests;
mod ticks;

pub use bars::stacked_bars;
pub use fit::fit_power_law;
pub use line::line_chart;
pub use scatter::scatter_loglog_with_fits;

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

/// Largest accepted image side, in pixels.
pub const MAX_SIDE: u32 = 16_384;

/// Registers the embedded fonts under [`FONT`] ([`text::register_fonts`]);
/// every drawing function calls it.
pub fn ensure_fonts() -> Result<(), PlotError> {
    text::register_fonts().map_err(PlotError::Font)
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
    /// Segment names, left of the stack first. Segment `i`
    /// always gets `PALETTE[i % 8]`: pass the same list to every figure
    /// (zeros allowed) and a phase keeps its colour across figures.
    /// Segments that are zero in every category are left out of the legend.
    pub segments: Vec<String>,
    /// The bars, top to bottom (bars grow to the right, so that long
    /// category names stay readable).
    pub categories: Vec<Category>,
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
