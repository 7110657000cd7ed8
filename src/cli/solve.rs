//! `lse-deform solve DIR -o X.mtx`: a problem given as Matrix Market
//! matrices (as `export-system` writes them, or one by one).

use std::path::PathBuf;

use clap::Args;
use lse_deform::export::{META_FILE, apply_meta, check_meta, read_meta};
use lse_deform::problem::LseProblem;
use lse_deform::{Error, LseSolver, Report, mtx};

use super::files::check_distinct;
use super::summary::finish_report;
use super::{MethodArgs, check_outputs, phase};

/// Arguments of `solve`.
#[derive(Args)]
pub struct SolveArgs {
    /// Directory holding A.mtx, C.mtx, B.mtx, D.mtx (and meta.json), as
    /// export-system writes it.
    dir: Option<PathBuf>,
    /// A (l × n, sparse); default DIR/A.mtx.
    #[arg(long)]
    a: Option<PathBuf>,
    /// C (l × k, dense); default DIR/C.mtx.
    #[arg(long)]
    c: Option<PathBuf>,
    /// B (m × n, sparse, one hard constraint per row in priority order);
    /// default DIR/B.mtx.
    #[arg(long)]
    b: Option<PathBuf>,
    /// D (m × k, dense); default DIR/D.mtx.
    #[arg(long)]
    d: Option<PathBuf>,
    /// meta.json of export-system (Laplacian rows, length scale); default
    /// DIR/meta.json when it exists.
    #[arg(long)]
    meta: Option<PathBuf>,
    #[command(flatten)]
    method: MethodArgs,
    /// Output: X (n × k) as a dense Matrix Market file.
    #[arg(long, short = 'o')]
    output: PathBuf,
    /// Write the report as JSON here.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Estimate the condition number of the factored matrix.
    #[arg(long)]
    condition: bool,
}

/// The path of one of `solve`'s matrices: the flag, else `DIR/NAME`.
fn matrix_path(
    flag: &Option<PathBuf>,
    dir: &Option<PathBuf>,
    name: &str,
) -> Result<PathBuf, Error> {
    match (flag, dir) {
        (Some(p), _) => Ok(p.clone()),
        (None, Some(d)) => Ok(d.join(name)),
        (None, None) => Err(lse_deform::error::ProblemError::InvalidArgument {
            message: format!(
                "no {name}: give a directory or --{}",
                name.trim_end_matches(".mtx").to_lowercase()
            ),
        }
        .into()),
    }
}

/// Runs `solve`.
pub(crate) fn solve(a: SolveArgs) -> Result<(), Error> {
    let path = |flag: &Option<PathBuf>, name: &str| matrix_path(flag, &a.dir, name);
    let (pa, pc, pb, pd) = (
        path(&a.a, "A.mtx")?,
        path(&a.c, "C.mtx")?,
        path(&a.b, "B.mtx")?,
        path(&a.d, "D.mtx")?,
    );
    let meta_path = a.meta.clone().or_else(|| {
        a.dir
            .as_ref()
            .map(|d| d.join(META_FILE))
            .filter(|p| p.exists())
    });
    // Fail fast, as `deform` does: both outputs must be other files than
    // the inputs, and writable, before the matrices are read and factored.
    let mut inputs = vec![
        ("the matrix A", pa.as_path()),
        ("the matrix C", pc.as_path()),
        ("the matrix B", pb.as_path()),
        ("the matrix D", pd.as_path()),
    ];
    inputs.extend(meta_path.as_deref().map(|p| ("the meta.json read", p)));
    inputs.extend(a.method.held.inputs());
    let mut outputs = vec![("-o", a.output.as_path())];
    outputs.extend(a.report.as_deref().map(|r| ("--report", r)));
    check_distinct(&inputs, &outputs)?;
    check_outputs(None, Some(&a.output))?;
    check_outputs(None, a.report.as_deref())?;
    let m = &a.method;
    let options = m.options()?.solve;
    let meta = meta_path
        .as_deref()
        .map(|p| read_meta(p).map(|m| (m, p)))
        .transpose()?;
    let bar = phase("reading the matrices");
    let t = std::time::Instant::now();
    let (ma, mc, mb, md) = mtx::read_system(&pa, &pc, &pb, &pd, options.resources.budget)?;
    if let Some((meta, path)) = &meta {
        check_meta(
            meta,
            path,
            ma.as_ref(),
            mc.as_ref(),
            mb.as_ref(),
            md.as_ref(),
        )?;
    }
    let mut problem = LseProblem::from_parts(ma.as_ref(), mc.as_ref(), mb.as_ref(), md.as_ref())?;
    if let Some((meta, path)) = &meta {
        problem = apply_meta(meta, path, problem)?;
    }
    let length_unit = meta.as_ref().and_then(|(m, _)| m.length_unit);
    let mut base = Report {
        length_unit: length_unit.unwrap_or(1.0),
        ..Report::default()
    };
    base.timings_s.setup = t.elapsed().as_secs_f64();
    bar.set_message(format!("precompute ({})", options.formulation.method));
    let mut solver = LseSolver::with_base_report(problem, base, &options)?;
    if a.condition {
        bar.set_message("condition estimate (Lanczos)");
        solver.estimate_condition()?;
    }
    bar.set_message("solve");
    let x = solver.solve()?;
    bar.finish_and_clear();
    finish_report(
        solver.report(),
        &[],
        a.report.as_deref(),
        ("unknowns", "rows of B"),
        || mtx::write_dense(&a.output, x.as_ref()),
    )
}
