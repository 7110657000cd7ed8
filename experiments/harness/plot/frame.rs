//! Drawing, generic over the backend: the [`Figure`] trait, saving as PNG
//! and SVG, markers, the frame (axes, grid, title) and the legend.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use super::ticks::{AxisTicks, TickCoord};
use super::{
    AXIS_DESC_SIZE, FONT, LEGEND_SIZE, LegendPosition, MAX_SIDE, Output, PlotError, TICK_SIZE,
    TITLE_SIZE, ensure_fonts,
};
use crate::harness::text::GoodText;

/// A figure that can be drawn on any backend.
pub(super) trait Figure {
    /// Draws the whole figure on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String>;
}

/// Draws `figure` to `out.png()` then `out.svg()`.
pub(super) fn save(figure: &impl Figure, out: &Output) -> Result<Vec<PathBuf>, PlotError> {
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
pub(super) fn de<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> String {
    e.to_string()
}

/// Point markers of successive series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Marker {
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
    pub(super) const ALL: [Marker; 4] = [
        Marker::Circle,
        Marker::Square,
        Marker::Triangle,
        Marker::Diamond,
    ];

    /// The marker's outline as pixel offsets from its centre, radius `r`.
    pub(super) fn outline(self, r: i32) -> Vec<(i32, i32)> {
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
pub(super) fn cross_strokes(r: i32) -> [Vec<(i32, i32)>; 2] {
    [vec![(-r, -r), (r, r)], vec![(-r, r), (r, -r)]]
}

/// A series ready to draw, in plotting coordinates.
#[derive(Debug, Clone)]
pub(super) struct PreparedSeries {
    /// Legend name.
    pub(super) name: String,
    /// Colour.
    pub(super) colour: RGBColor,
    /// Marker shape.
    pub(super) marker: Marker,
    /// Points.
    pub(super) points: Vec<(f64, f64)>,
    /// Failure markers (`None`: bottom edge).
    pub(super) failures: Vec<(f64, Option<f64>)>,
    /// Whether a fitted line is drawn in the series' colour (scatter).
    pub(super) has_fit: bool,
}

/// Title, axis descriptions and ticks of a 2-D chart.
#[derive(Debug, Clone)]
pub(super) struct Frame {
    /// Title.
    pub(super) title: String,
    /// Description of x.
    pub(super) x_label: String,
    /// Description of y.
    pub(super) y_label: String,
    /// Horizontal axis.
    pub(super) x: AxisTicks,
    /// Vertical axis.
    pub(super) y: AxisTicks,
    /// Vertical grid lines at x ticks.
    pub(super) x_grid: bool,
    /// Horizontal grid lines at y ticks.
    pub(super) y_grid: bool,
}

/// The chart type every figure draws on.
pub(super) type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<TickCoord, TickCoord>>;

impl Frame {
    /// Fills `root` white, lays out the chart (label areas sized to the
    /// measured tick labels) and draws axes, ticks, grid and descriptions.
    pub(super) fn build<'a, DB: DrawingBackend>(
        &self,
        root: &'a DrawingArea<DB, Shift>,
    ) -> Result<Chart<'a, DB>, String> {
        root.fill(&WHITE).map_err(de)?;
        let (x_area, y_area, right) = self.label_areas(root)?;
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
        self.draw_axes(&mut chart)?;
        Ok(chart)
    }

    /// The label areas of the frame on `root`, in pixels: below the x axis
    /// (tick labels and description), left of the y axis (the widest tick
    /// label and the description), and the right margin (room for the last
    /// x tick label, which is centred on the plot's edge).
    fn label_areas<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> Result<(u32, u32, u32), String> {
        let tick_style = TextStyle::from((FONT, TICK_SIZE).into_font());
        let desc_style = TextStyle::from((FONT, AXIS_DESC_SIZE).into_font());
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
        let last_x = &self.x.majors[self.x.majors.len().saturating_sub(1)..];
        let right = (width_of(last_x)? / 2 + 8).max(20);
        Ok((x_area, y_area, right))
    }

    /// Draws axes, tick labels, grid lines and axis descriptions.
    fn draw_axes<DB: DrawingBackend>(&self, chart: &mut Chart<'_, DB>) -> Result<(), String> {
        let x_fmt = |v: &f64| self.x.label(*v);
        let y_fmt = |v: &f64| self.y.label(*v);
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(self.x_label.as_str())
            .y_desc(self.y_label.as_str())
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .label_style((FONT, TICK_SIZE).into_font())
            .axis_desc_style((FONT, AXIS_DESC_SIZE).into_font())
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
        mesh.draw().map_err(de)
    }

    /// The legend position for `pos`, choosing for [`LegendPosition::Auto`]
    /// among the four corners and the four edge middles the place where a
    /// legend box of `size` (fractions of the plotting area) would cover
    /// the least of `polylines` (plot coordinates; points weigh 20, and with
    /// `join` each of 40 samples along a segment weighs 1). Ties go to the
    /// corners (upper right first).
    pub(super) fn legend_corner(
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
            LegendPosition::Auto => Some(self.least_covered(polylines, join, size)),
        }
    }

    /// Among the four corners and the four edge middles, the place where a
    /// legend box of `size` covers the least of `polylines` (see
    /// [`Frame::legend_corner`]).
    fn least_covered(
        &self,
        polylines: &[Vec<(f64, f64)>],
        join: bool,
        size: (f64, f64),
    ) -> SeriesLabelPosition {
        let nx = |x: f64| (x - self.x.lo) / (self.x.hi - self.x.lo);
        let ny = |y: f64| (y - self.y.lo) / (self.y.hi - self.y.lo);
        // Candidate boxes: (position, u range, v range), corners first
        // (preferred on ties).
        let (bw, bh) = size;
        let (left, centre, right) = ((0.0, bw), (0.5 - bw / 2.0, 0.5 + bw / 2.0), (1.0 - bw, 1.0));
        let (bottom, middle, top) = ((0.0, bh), (0.5 - bh / 2.0, 0.5 + bh / 2.0), (1.0 - bh, 1.0));
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
        // Cost: a data point or marker under the legend costs 20, each
        // sample along a line 1.
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
            if !join {
                continue;
            }
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
        let best = (0..candidates.len())
            .min_by_key(|&i| (costs[i], i))
            .unwrap_or(0);
        candidates[best].0.clone()
    }
}

/// The size of the legend box for `labels`, as fractions of the plotting
/// area of `chart` (with its margin, and a little slack).
pub(super) fn legend_size<'a, DB: DrawingBackend + 'a>(
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
pub(super) fn draw_legend<'a, DB: DrawingBackend + 'a>(
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
