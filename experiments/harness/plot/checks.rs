//! Validation of the data before anything is drawn: non-finite values are
//! errors, points a log axis cannot show are skipped and noted.

use super::{PlotError, Scale};

/// A [`PlotError::NoData`].
pub(super) fn no_data(figure: &str, detail: &str) -> PlotError {
    PlotError::NoData {
        figure: figure.to_string(),
        detail: detail.to_string(),
    }
}

/// The notes, or a generic phrase, as the detail of a [`PlotError::NoData`].
pub(super) fn skipped_detail(notes: &[String]) -> String {
    if notes.is_empty() {
        "no drawable point".into()
    } else {
        format!("no drawable point: {}", notes.join("; "))
    }
}

/// Errors with [`PlotError::NonFinite`] unless `v` is finite.
pub(super) fn check_finite(
    figure: &str,
    what: impl FnOnce() -> String,
    v: f64,
) -> Result<(), PlotError> {
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
pub(super) fn transform_points(
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
