//! Axis ranges, ticks and their labels (decades with superscripts on log
//! axes, round steps on linear axes, names on category axes).

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};

use super::{Axis, PlotError, Scale};

/// An axis in plotting coordinates (log10 of the data on log axes): range,
/// labelled major ticks and unlabelled minor grid lines.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct AxisTicks {
    /// Lower end.
    pub(super) lo: f64,
    /// Upper end.
    pub(super) hi: f64,
    /// Major ticks and their labels.
    pub(super) majors: Vec<(f64, String)>,
    /// Minor grid lines.
    pub(super) minors: Vec<f64>,
}

impl AxisTicks {
    /// Ticks for `axis`, fitted to `values` (plotting coordinates) unless the
    /// axis has a fixed range.
    pub(super) fn new(
        figure: &str,
        name: &'static str,
        axis: &Axis,
        values: &[f64],
    ) -> Result<AxisTicks, PlotError> {
        let (lo, hi) = match axis.range {
            Some((lo, hi)) => fixed_range(figure, name, axis.scale, lo, hi)?,
            None => fitted_range(axis.scale, values),
        };
        Ok(match axis.scale {
            Scale::Linear => AxisTicks::linear(lo, hi),
            Scale::Log10 => AxisTicks::log(lo, hi),
        })
    }

    /// Linear ticks over `[lo, hi]` (checked).
    pub(super) fn linear_fixed(figure: &str, lo: f64, hi: f64) -> Result<AxisTicks, PlotError> {
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
    pub(super) fn linear(lo: f64, hi: f64) -> AxisTicks {
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
    pub(super) fn log(lo: f64, hi: f64) -> AxisTicks {
        if hi.floor() - lo.ceil() >= 1.0 {
            AxisTicks::log_decades(lo, hi)
        } else {
            AxisTicks::log_multiples(lo, hi)
        }
    }

    /// Log ticks over at least two decades: every decade (or every second,
    /// third, … so that at most ~8 are labelled) a major tick, the others
    /// and, over at most ten decades, the multiples 2–9 minor grid lines.
    fn log_decades(lo: f64, hi: f64) -> AxisTicks {
        let first = lo.ceil() as i64;
        let last = hi.floor() as i64;
        let decades = last - first + 1;
        let inside = |t: f64| t >= lo - 1e-12 && t <= hi + 1e-12;
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
                let between = (2..=9).map(|m| t + (m as f64).log10());
                minors.extend(between.filter(|&tm| inside(tm)));
            }
        }
        AxisTicks {
            lo,
            hi,
            majors,
            minors,
        }
    }

    /// Log ticks over less than two decades: 1–2–5 multiples (or 1…9 when
    /// those give fewer than three), labelled as plain numbers; below a
    /// factor 2 of range, linear-looking ticks.
    fn log_multiples(lo: f64, hi: f64) -> AxisTicks {
        let inside = |t: f64| t >= lo - 1e-12 && t <= hi + 1e-12;
        let multiples = |mantissas: &[f64]| -> Vec<(f64, String)> {
            let decades = (lo.floor() as i64)..=(hi.ceil() as i64);
            decades
                .flat_map(|k| mantissas.iter().map(move |m| m * 10f64.powi(k as i32)))
                .filter(|v| inside(v.log10()))
                .map(|v| (v.log10(), plain_label(v)))
                .collect()
        };
        let mut majors = multiples(&[1.0, 2.0, 5.0]);
        if majors.len() < 3 {
            majors = multiples(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
        }
        if majors.len() < 2 {
            let lin = AxisTicks::linear(10f64.powf(lo), 10f64.powf(hi));
            majors = (lin.majors.into_iter())
                .filter(|(v, _)| *v > 0.0)
                .map(|(v, l)| (v.log10(), l))
                .collect();
        }
        AxisTicks {
            lo,
            hi,
            majors,
            minors: Vec::new(),
        }
    }

    /// A category axis: positions `0..n`, the first of `names` on top
    /// (at position `n − 1`).
    pub(super) fn categories(names: &[String]) -> AxisTicks {
        let n = names.len();
        let majors = (names.iter().enumerate())
            .map(|(i, name)| ((n - 1 - i) as f64, name.clone()))
            .collect();
        AxisTicks {
            lo: -0.6,
            hi: n as f64 - 0.4,
            majors,
            minors: Vec::new(),
        }
    }

    /// The label of the major tick at `v`, or an empty string.
    pub(super) fn label(&self, v: f64) -> String {
        let tol = 1e-9 * (1.0 + (self.hi - self.lo).abs());
        self.majors
            .iter()
            .find(|(t, _)| (t - v).abs() <= tol)
            .map(|(_, l)| l.clone())
            .unwrap_or_default()
    }

    /// The plotters coordinate of this axis.
    pub(super) fn coord(&self) -> TickCoord {
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
pub(super) struct TickCoord {
    /// Lower end.
    pub(super) lo: f64,
    /// Upper end.
    pub(super) hi: f64,
    /// Major key points.
    pub(super) majors: Vec<f64>,
    /// Minor key points.
    pub(super) minors: Vec<f64>,
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
pub(super) fn nice_step(raw: f64) -> f64 {
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
pub(super) fn superscript(k: i64) -> String {
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
pub(super) fn scientific_label(v: f64) -> String {
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
pub(super) fn plain_label(v: f64) -> String {
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

/// A fixed axis range in plotting coordinates, checked: finite, `lo < hi`,
/// and `lo > 0` on a log axis.
fn fixed_range(
    figure: &str,
    name: &'static str,
    scale: Scale,
    lo: f64,
    hi: f64,
) -> Result<(f64, f64), PlotError> {
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
    match scale {
        Scale::Linear => Ok((lo, hi)),
        Scale::Log10 if lo <= 0.0 => Err(bad("a log axis needs lo > 0")),
        Scale::Log10 => Ok((lo.log10(), hi.log10())),
    }
}

/// The range of `values` (plotting coordinates) padded by 5 % on each
/// side; a single value gets half a decade (log) or 10 % of it, at least
/// 0.5 (linear) on each side, no value `[0, 1]`.
fn fitted_range(scale: Scale, values: &[f64]) -> (f64, f64) {
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
        let half = match scale {
            Scale::Log10 => 0.5,
            Scale::Linear => (0.1 * lo.abs()).max(0.5),
        };
        lo -= half;
        hi += half;
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}
