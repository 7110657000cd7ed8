//! `python`: what the Python door costs and whether it agrees with libigl.
//!
//! The package is installed into the Python of
//! [`environment::python_with_package`] (this checkout, `pip install .`);
//! `experiments/python_door.py` then solves the paper's position-only
//! scene on the Bunny (else a generated bumpy sphere) through the module
//! and through libigl's `min_quad_with_fixed` (max difference over the
//! bounding-box diagonal, target ≤ 1e-9), and times precompute + solve
//! through Python, alternated round by round with the same calls timed
//! inside this process (null-space QR, cotangent Laplacian: the module's
//! defaults), target Python / Rust ≤ 1.1. Without a Python the section
//! says what was not measured and why.

use std::fmt::Write as _;
use std::io::{BufRead, BufReader, Write as _};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Stdio};
use std::time::Instant;

use lse_deform::mesh::write_mesh;
use lse_deform::scene::FixedAndHandle;
use lse_deform::{Deformer, LaplacianKind, Method, formulation::FormulationChoice};
use serde::{Deserialize, Serialize};

use crate::harness::context::AnyError;
use crate::harness::context::{Context, MeshCase};
use crate::harness::environment::{self, Python};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{markdown_table, median};

pub const NAME: &str = "python";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "The Python door — its cost against Rust and its agreement with libigl",
    inputs: &[Input::OneMesh, Input::Python],
    run,
};

/// Python / Rust median ratio the door must stay within.
const RATIO_LIMIT: f64 = 1.1;
/// Largest difference from libigl, over the bounding-box diagonal.
const LIBIGL_LIMIT: f64 = 1e-9;

/// The script's first line: the libigl agreement and the versions.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Agreement {
    vertices: usize,
    constraints: usize,
    libigl_max_difference_over_diagonal: f64,
    forward_error_estimate: f64,
    libigl_solve_s: f64,
    python_version: String,
    numpy_version: String,
    scipy_version: String,
    libigl_version: String,
}

/// One alternated round: precompute + solve through each door.
#[derive(Debug, Clone, Serialize)]
struct Round {
    round: usize,
    python_s: f64,
    rust_s: f64,
}

/// The Python process of `python_door.py`, answering one round per line.
struct Door {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl Door {
    fn start(python: &Python, mesh: &Path, scene: &Path) -> Result<Door, AnyError> {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python_door.py");
        let mut child = environment::child(&python.exe)
            .arg(script)
            .arg(mesh)
            .arg(scene)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()?;
        let stdin = child.stdin.take().ok_or("no stdin")?;
        let stdout = BufReader::new(child.stdout.take().ok_or("no stdout")?);
        Ok(Door {
            child,
            stdin,
            stdout,
        })
    }

    fn line<T: for<'de> Deserialize<'de>>(&mut self) -> Result<T, AnyError> {
        let mut line = String::new();
        if self.stdout.read_line(&mut line)? == 0 {
            return Err("python_door.py ended early (its error is on stderr)".into());
        }
        Ok(serde_json::from_str(&line)?)
    }

    /// One precompute + solve through Python, in seconds.
    fn round(&mut self) -> Result<f64, AnyError> {
        writeln!(self.stdin, "run")
            .and_then(|()| self.stdin.flush())
            .map_err(|e| format!("python_door.py ended early (its error is on stderr): {e}"))?;
        #[derive(Deserialize)]
        struct Seconds {
            seconds: f64,
        }
        Ok(self.line::<Seconds>()?.seconds)
    }
}

impl Drop for Door {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The agreement and `rounds` alternated rounds (after one warm-up each).
fn measure(
    python: &Python,
    case: &MeshCase,
    rounds: usize,
) -> Result<(Agreement, Vec<Round>), AnyError> {
    let constraints = FixedAndHandle::paper_default(&case.mesh).constraints(&case.mesh)?;
    let io = std::env::temp_dir().join(format!("lse-python-door-{}", std::process::id()));
    std::fs::create_dir_all(&io)?;
    let (mesh_file, scene) = (io.join("mesh.obj"), io.join("scene.json"));
    write_mesh(&case.mesh, &mesh_file)?;
    std::fs::write(&scene, constraints.to_json())?;
    let mut door = Door::start(python, &mesh_file, &scene)?;
    let result = alternate(&mut door, &case.mesh, constraints, rounds);
    drop(door);
    let _ = std::fs::remove_dir_all(&io);
    result
}

/// The script's agreement line, then `rounds` alternated rounds after one
/// warm-up round each.
fn alternate(
    door: &mut Door,
    mesh: &lse_deform::Mesh,
    constraints: lse_deform::ConstraintSet,
    rounds: usize,
) -> Result<(Agreement, Vec<Round>), AnyError> {
    let agreement: Agreement = door.line()?;
    let formulation = FormulationChoice::new(Method::NullSpaceQr).build()?;
    let mut deformer = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        constraints,
        &lse_deform::SolveOptions::default(),
    )?;
    let mut rust = || -> Result<f64, AnyError> {
        let t = Instant::now();
        deformer.refactor_with(
            formulation.as_ref(),
            &lse_deform::resources::Resources::default(),
        )?;
        std::hint::black_box(deformer.solve()?);
        Ok(t.elapsed().as_secs_f64())
    };
    rust()?;
    door.round()?;
    let mut rows = Vec::with_capacity(rounds);
    for round in 1..=rounds {
        let rust_s = rust()?;
        let python_s = door.round()?;
        rows.push(Round {
            round,
            python_s,
            rust_s,
        });
    }
    Ok((agreement, rows))
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let dir = ctx.dir(NAME)?;
    let case = ctx.fallback_mesh("bunny-35k-stanford.obj", 35_000, 3_000)?;
    let rounds = if ctx.quick { 3 } else { 11 };
    let measured = environment::python_with_package()
        .map_err(AnyError::from)
        .and_then(|python| Ok((measure(&python, &case, rounds)?, python)));
    let (md, summary) = match measured {
        Ok(((agreement, rows), python)) => {
            ctx.write_rows(&dir.join("agreement"), std::slice::from_ref(&agreement))?;
            ctx.write_rows(&dir.join("rounds"), &rows)?;
            let (md, headline) = measured_section(ctx, &case, &python, &agreement, &rows);
            (md, Summary::measured(headline))
        }
        Err(why) => {
            let (md, why) = not_measured_section(ctx, &why.to_string());
            (md, Summary::skipped(why))
        }
    };
    ctx.write_section(NAME, &md)?;
    ctx.write_page(NAME, EXPERIMENT.title, &md)?;
    Ok(summary)
}

fn verdict(met: bool) -> &'static str {
    if met { "met" } else { "**missed**" }
}

/// The section and headline from the measured rows.
fn measured_section(
    ctx: &Context,
    case: &MeshCase,
    python: &Python,
    a: &Agreement,
    rows: &[Round],
) -> (String, String) {
    let py: Vec<f64> = rows.iter().map(|r| r.python_s).collect();
    let rs: Vec<f64> = rows.iter().map(|r| r.rust_s).collect();
    let (mp, mr) = (median(&py), median(&rs));
    let ratio = mp / mr;
    let gap = a.libigl_max_difference_over_diagonal;
    let mut s = String::new();
    s.push_str(&ctx.regenerate(NAME));
    let _ = writeln!(
        s,
        "The package of this checkout installed with `pip install .` (maturin) into {}; Python {}, numpy {}, scipy {}, libigl {}. \
         Scene: the paper's fixed 20 % and 2 % handle on {} ({} vertices, {} hard position constraints), cotangent Laplacian, null-space QR (the module's defaults).\n",
        python.origin,
        a.python_version,
        a.numpy_version,
        a.scipy_version,
        a.libigl_version,
        case.name,
        a.vertices,
        a.constraints
    );
    let table = vec![
        vec![
            "libigl agreement: max \\|U − U_igl\\| / diagonal (`min_quad_with_fixed` on libigl's own `cotmatrix` and Voronoi `massmatrix`)".into(),
            format!("{gap:.1e}"),
            format!("≤ {LIBIGL_LIMIT:.0e}"),
            verdict(gap <= LIBIGL_LIMIT).into(),
        ],
        vec![
            format!("precompute + solve, Python / Rust, medians of {} alternated rounds ({:.3} s / {:.3} s)", rows.len(), mp, mr),
            format!("{ratio:.3}"),
            format!("≤ {RATIO_LIMIT}"),
            verdict(ratio <= RATIO_LIMIT).into(),
        ],
    ];
    s.push_str(&markdown_table(
        &["measure", "value", "target", "status"],
        &table,
    ));
    let _ = writeln!(
        s,
        "\nOur forward-error estimate on this scene is {:.1e} of the diagonal, so the difference from libigl is libigl's: it factors `LᵀL` (the squared condition number) without refinement; its solve took {:.3} s. \
         Each round times `Deformer.precompute(); Deformer.solve()` in one warm Python process and `Deformer::precompute` + `solve` inside this process, one after the other, after one discarded warm-up round each.",
        a.forward_error_estimate, a.libigl_solve_s
    );
    s.push_str(&ctx.closing(
        &[],
        "Data: `python/agreement.csv` (and `.json`), `python/rounds.csv` (every round).",
    ));
    let headline = format!(
        "{}: Python/Rust precompute+solve {ratio:.3} (medians {mp:.3} s / {mr:.3} s); libigl agreement {gap:.1e} × diagonal",
        case.name
    );
    (s, headline)
}

/// The section when no Python with the package and libigl could be found
/// or created: what was not measured and why.
fn not_measured_section(ctx: &Context, why: &str) -> (String, String) {
    let mut s = String::new();
    s.push_str(&ctx.regenerate(NAME));
    let _ = writeln!(
        s,
        "**Not measured:** the Python door's cost (Python against Rust precompute + solve) and its agreement with libigl, because {why}. \
         The experiment uses `$LSE_PYTHON` if set, else creates the virtual environment `{}` (`python3 -m venv`, `pip install numpy scipy libigl`, then `pip install .` of this checkout).",
        environment::VENV
    );
    s.push_str(&ctx.closing(&[], "No data files."));
    (s, format!("not measured: {why}"))
}
