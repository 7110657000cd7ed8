//! Tests of the plots: fits, skips and errors, ticks, and one figure of
//! each kind drawn to PNG and SVG.

use super::fit::FitError;
use super::ticks::AxisTicks;
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
    assert!(
        (10f64.powf(fit.intercept + fit.slope * 200f64.log10()) / (3.5 * 200f64.powf(1.37)) - 1.0)
            .abs()
            < 1e-12
    );
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
