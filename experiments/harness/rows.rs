//! The cells, tables and statistics of the sections and data files:
//! times, optional numbers, medians and percentiles, Markdown tables.

use std::fmt::Write as _;

/// Formats seconds for tables: ms below one second.
pub fn fmt_time(seconds: f64) -> String {
    if seconds < 1.0 {
        format!("{:.1} ms", seconds * 1e3)
    } else {
        format!("{seconds:.2} s")
    }
}

/// Median of a non-empty slice (NaN for an empty one).
pub fn median(values: &[f64]) -> f64 {
    percentile(values, 0.5)
}

/// The `q`-quantile (nearest rank) of the values.
pub fn percentile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let idx = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
    v[idx]
}

/// A markdown table from a header and rows.
pub fn markdown_table(header: &[&str], rows: &[Vec<String>]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "| {} |", header.join(" | "));
    let _ = writeln!(s, "|{}", "---|".repeat(header.len()));
    for r in rows {
        let _ = writeln!(s, "| {} |", r.join(" | "));
    }
    s
}

/// A CSV cell of an optional number: `{:.6e}`, empty for `None`.
pub fn cell_f(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.6e}")).unwrap_or_default()
}

/// A CSV cell of an optional count, empty for `None`.
pub fn cell_u(v: Option<usize>) -> String {
    v.map(|x| x.to_string()).unwrap_or_default()
}
