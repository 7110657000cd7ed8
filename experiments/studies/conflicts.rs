//! Experiment `conflicts`: the paper's Fig. 6 — hard constraints that
//! contradict each other. Soft compromise (every constraint soft, or every
//! hard row a penalty row) against detect-and-remove (the null-space QR's
//! rank detection, which keeps the earlier constraint of a conflicting pair
//! and reports the later one with its residual), and KKT, which has no
//! rank detection.
//!
//! Scene ([`scene`]): the Table 1 scene (20 % fixed, 2 % handle moved by
//! 15 % of the diagonal), then, appended in this order (lower priority):
//! duplicates of some fixed constraints (redundant), a second position
//! constraint on some handle vertices pulling them back to where they were
//! (conflicting), and relative constraints between a handle vertex and a
//! fixed vertex keeping their original difference (conflicting: the
//! difference of two rows already present).

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use lse_deform::Report;
use lse_deform::mesh::Mesh;

use crate::harness::conflict_scene::{
    GROUPS, Scene, Solved, conflict_mesh, residuals, scene, solve_all,
};
use crate::harness::context::AnyError;
use crate::harness::context::Context;
use crate::harness::measures::sci;
use crate::harness::plot::{self, Axis, LegendPosition, LineChart, Output, Series};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{fmt_time, markdown_table};

/// The folder and command-line word of this experiment.
pub const NAME: &str = "conflicts";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "Conflicting constraints (paper Fig. 6)",
    inputs: &[Input::Meshes],
    run,
};

/// The solves of the scene and what is derived from them.
struct Outcome<'a> {
    sc: &'a Scene,
    solved: Vec<Solved>,
    /// Per method, the residual of every constraint (absolute).
    per_method: Vec<Option<Vec<f64>>>,
    /// The null-space method's report (the last method).
    ns_report: Option<Report>,
    diag: f64,
}

impl Outcome<'_> {
    fn new<'a>(mesh: &Mesh, sc: &'a Scene) -> Result<Outcome<'a>, AnyError> {
        let solved = solve_all(mesh, sc)?;
        let per_method = solved
            .iter()
            .map(|s| {
                s.result
                    .as_ref()
                    .ok()
                    .map(|(x, _)| residuals(&sc.constraints, x))
            })
            .collect();
        let ns_report = solved
            .last()
            .and_then(|s| s.result.as_ref().ok().map(|(_, r)| r.clone()));
        Ok(Outcome {
            sc,
            solved,
            per_method,
            ns_report,
            diag: mesh.bbox_diagonal(),
        })
    }

    /// What the null-space method did with constraint `i`.
    fn status_of(&self, i: usize) -> String {
        match &self.ns_report {
            Some(r) if r.redundant.contains(&i) => "redundant (dropped)".into(),
            Some(r) if r.conflicting.iter().any(|c| c.index == i) => "conflicting (dropped)".into(),
            Some(_) => "kept".into(),
            None => String::new(),
        }
    }

    /// `conflicts.csv`: one row per constraint, a residual column per method.
    fn write_data(&self, ctx: &Context, dir: &Path) -> Result<(), AnyError> {
        let mut header: Vec<String> = ["index", "group", "kind", "vertices", "nullspace_status"]
            .map(String::from)
            .to_vec();
        for s in &self.solved {
            header.push(format!("residual_relative[{}]", s.label));
        }
        let header_refs: Vec<&str> = header.iter().map(|s| s.as_str()).collect();
        let rows: Vec<Vec<String>> = (self.sc.constraints.as_slice().iter().enumerate())
            .map(|(i, c)| {
                let vertices: Vec<String> =
                    c.kind.vertices().iter().map(|v| v.to_string()).collect();
                let mut row = vec![
                    i.to_string(),
                    GROUPS[self.sc.group[i]].to_string(),
                    c.kind.name().to_string(),
                    vertices.join(" "),
                    self.status_of(i),
                ];
                for r in &self.per_method {
                    row.push(
                        r.as_ref()
                            .map(|r| format!("{:e}", r[i] / self.diag))
                            .unwrap_or_default(),
                    );
                }
                row
            })
            .collect();
        ctx.write_csv(&dir.join("conflicts.csv"), &header_refs, &rows)
    }

    /// Max residual / diagonal per group and method, and what null-space QR
    /// dropped.
    fn group_table(&self) -> String {
        let mut table = Vec::new();
        for (g, gname) in GROUPS.iter().enumerate() {
            let idx: Vec<usize> = (0..self.sc.group.len())
                .filter(|&i| self.sc.group[i] == g)
                .collect();
            let mut row = vec![gname.to_string(), idx.len().to_string()];
            for r in &self.per_method {
                row.push(match r {
                    Some(r) => sci(idx.iter().map(|&i| r[i]).fold(0.0, f64::max) / self.diag),
                    None => "–".into(),
                });
            }
            let dropped = idx.iter().filter(|&&i| self.status_of(i) != "kept").count();
            row.push(format!("{dropped} of {}", idx.len()));
            table.push(row);
        }
        let mut header = vec!["group".to_string(), "constraints".into()];
        for s in &self.solved {
            header.push(format!("max res / diag: {}", s.label));
        }
        header.push("dropped by null-space QR".into());
        let refs: Vec<&str> = header.iter().map(|s| s.as_str()).collect();
        markdown_table(&refs, &table)
    }

    /// The index of the first appended constraint.
    fn first_extra(&self) -> usize {
        self.sc.group.iter().position(|&g| g >= 2).unwrap_or(0)
    }

    /// The residual of every constraint, one series per method.
    fn figure(&self, dir: &Path, name: &str) -> Result<(), AnyError> {
        let floor = 1e-17;
        let series: Vec<Series> = self
            .solved
            .iter()
            .zip(&self.per_method)
            .filter_map(|(s, r)| {
                let points = r.as_ref()?.iter().enumerate();
                let points = points.map(|(i, v)| (i as f64, (v / self.diag).max(floor)));
                Some(Series::new(s.label.clone(), points.collect()))
            })
            .collect();
        if series.is_empty() {
            return Ok(());
        }
        let chart = LineChart {
            title: format!(
                "Conflicting constraints on {name}: residual of each constraint (appended groups from index {})",
                self.first_extra()
            ),
            x: Axis::linear("constraint index (list order = priority)"),
            y: Axis::log10("‖b_k X − d_k‖ / diagonal (≥ 1e-17)"),
            series,
            reference_lines: Vec::new(),
            legend: LegendPosition::Auto,
        };
        plot::line_chart(
            &chart,
            &Output::new(dir.join("conflicts")).with_size(1100, 640),
        )?;
        Ok(())
    }

    /// What null-space QR kept and dropped, for its outcome line.
    fn null_space_detail(&self, r: &Report) -> String {
        let conflicting: Vec<String> = r
            .conflicting
            .iter()
            .map(|c| format!("#{} (residual {})", c.index, sci(c.residual / self.diag)))
            .collect();
        format!(
            "; rank {} of {} hard rows; redundant (dropped, satisfied anyway): {:?}; conflicting (dropped): {}",
            r.rank.map(|k| k.to_string()).unwrap_or_default(),
            r.hard_constraints,
            r.redundant,
            conflicting.join(", ")
        )
    }

    /// One line per method: solved (residuals) or failed.
    fn outcome_text(&self) -> String {
        let mut s = String::new();
        let n = self.sc.constraints.len();
        for (i, (sv, res)) in self.solved.iter().zip(&self.per_method).enumerate() {
            let (_, r) = match &sv.result {
                Ok(ok) => ok,
                Err(e) => {
                    let _ = writeln!(s, "- {}: **failed** — {e}", sv.label);
                    continue;
                }
            };
            let all = res
                .as_ref()
                .map_or(f64::NAN, |v| v.iter().fold(0.0, |a: f64, &b| a.max(b)));
            let kept = if r.hard_constraints == 0 {
                "– (none: all soft)".to_string()
            } else {
                sci(r.max_constraint_residual_relative)
            };
            // The null-space method is the last one.
            let detail = if i + 1 == self.solved.len() {
                self.null_space_detail(r)
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "- {}: solved; max residual over all {n} constraints {} of the diagonal, over the hard constraints it keeps {kept}{detail}",
                sv.label,
                sci(all / self.diag),
            );
        }
        s
    }
}

/// The section, from the outcome.
fn section(
    ctx: &Context,
    name: &str,
    mesh: &Mesh,
    extra: usize,
    o: &Outcome,
    seconds: f64,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Scene on {name} ({} vertices, cotangent Laplacian): the Table 1 scene ({} fixed, {} handle vertices, handle moved by 15 % of the diagonal), \
         then appended (lower priority): {extra} duplicates of fixed constraints (redundant), {extra} handle vertices pinned a second time at their \
         original position (conflict of size 0.15·diagonal), and {extra} relative constraints between a handle and a fixed vertex keeping their \
         original difference (a conflict that is a combination of two earlier rows). {} constraints in all.\n",
        mesh.n_vertices(),
        o.sc.fixed.len(),
        o.sc.handle.len(),
        o.sc.constraints.len()
    );
    let _ = writeln!(s, "**Outcome per method.**\n\n{}", o.outcome_text());
    let _ = writeln!(
        s,
        "**Maximum residual per group** (‖b_k X − d_k‖ / diagonal; the conflicting groups cannot all be met, so some residual there is unavoidable):\n"
    );
    s.push_str(&o.group_table());
    let _ = writeln!(
        s,
        "\nHow to read it: a soft compromise spreads the contradiction over both partners of each conflicting pair — the handle no longer reaches \
         its target and the fixed region moves — and nothing says which constraints disagree; detect-and-remove keeps the earlier constraint \
         of each pair exactly (residual at rounding level) and names the later one with its residual. KKT has no rank detection: its \
         matrix is singular.\n"
    );
    let _ = writeln!(
        s,
        "![residual per constraint](conflicts/conflicts.png)\n\n\
         How to read the figure: x is the constraint's position in the list (fixed, handle, then the appended groups from index {}); \
         y its residual over the diagonal on a log axis (exact zeros drawn at 1e-17). The null-space line stays at rounding level except at \
         the dropped conflicting constraints; the soft lines are high everywhere near the conflicts. Renders: see the Renders section.\n",
        o.first_extra()
    );
    let _ = writeln!(
        s,
        "Data: [`conflicts/conflicts.csv`](conflicts/conflicts.csv) (one row per constraint, with the null-space status). \
         Regenerate: `cargo run --release --bin experiments -- {NAME}{} --out results` ({} on {}).",
        ctx.mesh_args(),
        fmt_time(seconds),
        ctx.machine.cpu
    );
    s
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let started = Instant::now();
    let dir = ctx.dir(NAME)?;
    let (name, mesh) = conflict_mesh(ctx)?;
    let extra = 5;
    let sc = scene(&mesh, extra)?;
    let o = Outcome::new(&mesh, &sc)?;
    o.write_data(ctx, &dir)?;
    o.figure(&dir, &name)?;
    let seconds = started.elapsed().as_secs_f64();
    ctx.write_section(NAME, &section(ctx, &name, &mesh, extra, &o, seconds))?;
    let headline = match &o.ns_report {
        Some(r) => format!(
            "null-space QR dropped {} redundant + {} conflicting of {} appended; kept rows at {}; KKT {}",
            r.redundant.len(),
            r.conflicting.len(),
            3 * extra,
            sci(r.max_constraint_residual_relative),
            if o.solved[2].result.is_ok() {
                "solved"
            } else {
                "failed"
            }
        ),
        None => "null-space QR failed".into(),
    };
    Ok(Summary::measured(headline))
}
