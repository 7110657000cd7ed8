//! What `deform` and `solve` print and write after a solve: warnings, the
//! report file, the one-line summary, and the `--strict` checks.

use std::path::Path;

use lse_deform::report::{Warning, WarningKind};
use lse_deform::{Error, Report};

use super::write_text;

/// Conflict warnings, the outputs and the summary line of `deform` and
/// `solve`. `write_output` writes the command's result; it and the
/// `--report` file are staged together ([`lse_deform::atomic::staged`]):
/// either both replace their files or neither does. `input_warnings` were
/// printed when the inputs were read; they go first into the report file.
pub(crate) fn finish_report(
    report: &Report,
    input_warnings: &[String],
    path: Option<&Path>,
    (unknowns, constraints): (&str, &str),
    write_output: impl FnOnce() -> Result<(), Error>,
) -> Result<(), Error> {
    // The conflicting constraints are among the warnings (the first few one
    // by one, the rest counted: a file can hold 10⁵ of them).
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    super::staged(|| {
        write_output()?;
        match path {
            Some(path) => write_report(report, input_warnings, path),
            None => Ok(()),
        }
    })?;
    eprintln!("{}", summary_line(report, unknowns, constraints));
    Ok(())
}

/// An input warning (the constraints file names another mesh:
/// [`super::constraints_with_warnings`]) as the report's typed warning.
pub(crate) fn mismatch_warning(text: &str) -> Warning {
    Warning::new(WarningKind::ConstraintsMeshMismatch, text)
}

/// Writes `report` as JSON to `path`, `input_warnings` before its own.
pub(crate) fn write_report(
    report: &Report,
    input_warnings: &[String],
    path: &Path,
) -> Result<(), Error> {
    let json = if input_warnings.is_empty() {
        serde_json::to_string_pretty(report)
    } else {
        let mut full = report.clone();
        full.warnings
            .splice(0..0, input_warnings.iter().map(|w| mismatch_warning(w)));
        serde_json::to_string_pretty(&full)
    }
    .map_err(|e| Error::io(path, e.into()))?;
    write_text(path, json)
}

/// The one-line summary of a deformation or solve on stderr.
pub(crate) fn summary_line(report: &Report, unknowns: &str, constraints: &str) -> String {
    let t = &report.timings_s;
    let rank = report
        .rank
        .map(|r| format!("rank {r} of "))
        .unwrap_or_default();
    let dependence = if report.redundant.is_detected() {
        format!(
            "{} redundant, {} conflicting",
            report.redundant.len(),
            report.conflicting.len()
        )
    } else {
        "redundancy and conflicts not detected".into()
    };
    // A mesh's residuals are lengths, relative ones fractions of its
    // bounding-box diagonal; a general problem's are in its own units,
    // relative to its length scale.
    let (absolute, relative) = if unknowns == "vertices" {
        (" mesh units", "× diagonal")
    } else {
        ("", "relative")
    };
    let refinement = report
        .refinement
        .as_ref()
        .map(|r| {
            format!(
                ", refine {} ({} steps, {:.4} s), forward error ~{:.1e} {relative}",
                r.mode, r.steps, t.refine, r.forward_error_estimate
            )
        })
        .unwrap_or_default();
    format!(
        "{}: {} {unknowns}, {rank}{} hard {constraints} ({dependence}), max |BX - D| = {:.2e}{absolute} ({:.1e} {relative}); set-up {:.3} s, precompute {:.3} s, solve {:.4} s{refinement}{}",
        report.method,
        report.vertices,
        report.hard_constraints,
        report.max_constraint_residual,
        report.max_constraint_residual_relative,
        t.setup,
        t.precompute(),
        t.solve,
        report
            .condition_estimate
            .as_ref()
            .map(|c| format!(", condition ~{:.2e}", c.value))
            .unwrap_or_default()
    )
}
