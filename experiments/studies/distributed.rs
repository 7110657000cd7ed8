//! `distributed`: MUMPS on one and two MPI ranks, run as the `lse-deform`
//! command-line tool under `mpirun` (rank 0 reads, assembles and drives;
//! the other ranks serve its MUMPS commands), on the Bunny, Igea 537k and a
//! generated icosphere of about 650k vertices, each with the scene
//! `lse-deform scene` writes for it.
//!
//! Per run: MUMPS's analysis (`JOB = 1`, the report's `timings_s.symbolic`),
//! factorisation (`JOB = 2`, `numeric`) and solve (`JOB = 3` plus the
//! library's checks, `solve`); each rank's share of the factor
//! (`INFO(27)`) and the bytes MUMPS used on it (`INFO(22)`), from the
//! report's `mumps` object; each process's peak resident set (GNU time's
//! `%M`, when `/usr/bin/time` exists); and the largest vertex distance to
//! the faer-auto result of the same command without MPI, relative to the
//! rest mesh's bounding-box diagonal. The faer run and a one-rank run out
//! of core give the memory of the three settings.
//!
//! From the one-rank runs it fits `nnz(L) ≈ c·n·log₂n` (and MUMPS's bytes
//! likewise, least squares through the origin) and projects the per-rank
//! factor and memory to 20 M and 100 M vertices on 8 and 64 ranks: a
//! projection, not a measurement.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use lse_deform::mesh::read_mesh;
use serde::Serialize;
use serde_json::Value;

use crate::harness::context::{AnyError, Context};
use crate::harness::environment;
use crate::harness::plot::{self, Category, LegendPosition, Output, StackedBars};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{fmt_time, markdown_table};
use crate::harness::timing::{link, note_drawn};

/// The folder and command-line word of this experiment.
pub const NAME: &str = "distributed";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "Distributed MUMPS: one and two MPI ranks, and a projection",
    inputs: &[Input::Meshes, Input::Mumps],
    run,
};

/// The environment of every `mpirun`: Open MPI (the library links
/// Debian's) allowed to run as root, shared-memory transport without the
/// single-copy mechanism containers refuse, as many ranks as asked on
/// however many cores, and one BLAS thread per rank.
const MPI_ENV: [(&str, &str); 6] = [
    ("OMPI_ALLOW_RUN_AS_ROOT", "1"),
    ("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1"),
    ("OMPI_MCA_pml", "ob1"),
    ("OMPI_MCA_btl_vader_single_copy_mechanism", "none"),
    ("OMPI_MCA_rmaps_base_oversubscribe", "1"),
    ("OPENBLAS_NUM_THREADS", "1"),
];

/// The transports of every `mpirun`: the process itself and TCP over the
/// loopback interface (all ranks on this machine).
const MPI_ARGS: [&str; 6] = [
    "--mca",
    "btl",
    "self,tcp",
    "--mca",
    "btl_tcp_if_include",
    "lo",
];

/// How one run factors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Setting {
    /// `--factor faer-auto` (the default), no MPI: the reference.
    Faer,
    /// `--factor mumps` under `mpirun -np ranks`, in core.
    Mumps { ranks: usize },
    /// `--factor mumps --out-of-core DIR` under `mpirun -np 1`.
    OutOfCore,
}

impl Setting {
    /// Every setting, in the order of the tables.
    const ALL: [Setting; 4] = [
        Setting::Faer,
        Setting::Mumps { ranks: 1 },
        Setting::Mumps { ranks: 2 },
        Setting::OutOfCore,
    ];

    /// Processes of the run.
    fn ranks(self) -> usize {
        match self {
            Setting::Mumps { ranks } => ranks,
            Setting::Faer | Setting::OutOfCore => 1,
        }
    }

    /// The words of the tables.
    fn label(self) -> String {
        match self {
            Setting::Faer => "faer-auto, no MPI".into(),
            Setting::Mumps { ranks: 1 } => "MUMPS, 1 rank".into(),
            Setting::Mumps { ranks } => format!("MUMPS, {ranks} ranks"),
            Setting::OutOfCore => "MUMPS, 1 rank, out of core".into(),
        }
    }

    /// The stem of the run's files in the scratch directory.
    fn stem(self) -> String {
        match self {
            Setting::Faer => "faer".into(),
            Setting::Mumps { ranks } => format!("mumps{ranks}"),
            Setting::OutOfCore => "mumps1-ooc".into(),
        }
    }
}

/// One row of the data: one mesh in one setting.
#[derive(Debug, Clone, Serialize)]
struct Row {
    mesh: String,
    vertices: usize,
    setting: String,
    ranks: usize,
    /// Run under `mpirun` with `--factor mumps`.
    mumps: bool,
    out_of_core: bool,
    /// `timings_s.symbolic`: MUMPS's analysis (`JOB = 1`), or faer's
    /// symbolic factorisation.
    analysis_s: Option<f64>,
    /// `timings_s.numeric`: the factorisation (`JOB = 2`).
    factorisation_s: Option<f64>,
    /// `timings_s.solve`: the solve (`JOB = 3` plus the library's checks).
    solve_s: Option<f64>,
    /// Entries of the whole factor (`nnz.factor`).
    factor_entries: Option<u64>,
    /// MUMPS: each rank's share of the factor (`INFO(27)`).
    factor_entries_per_rank: Vec<u64>,
    /// MUMPS: the bytes each rank's factorisation used (`INFO(22)`).
    peak_bytes_per_rank: Vec<u64>,
    /// Each process's peak resident set (GNU time), bytes.
    peak_rss_per_rank: Vec<u64>,
    ordering: Option<String>,
    /// Largest vertex distance to the faer-auto result over the rest
    /// mesh's bounding-box diagonal.
    max_difference_to_faer: Option<f64>,
    status: String,
}

/// A mesh file to run on.
struct Case {
    name: String,
    path: PathBuf,
    source: String,
}

/// The programs of the runs and the scratch directory of their files.
struct Tools {
    bin: PathBuf,
    mpirun: PathBuf,
    time: Option<PathBuf>,
    scratch: PathBuf,
}

impl Tools {
    /// The command that runs `lse-deform` in `setting`: directly, or under
    /// `mpirun`; with GNU time each process writes its peak resident set
    /// (KiB) to `PREFIX.RANK`, `prefix` = `rss`.
    fn command(&self, setting: Setting, rss: &Path) -> Command {
        if setting == Setting::Faer {
            return match &self.time {
                Some(time) => {
                    let mut c = environment::child(time);
                    c.args(["-f", "%M", "-o"])
                        .arg(rank_file(rss, 0))
                        .arg(&self.bin);
                    c
                }
                None => environment::child(&self.bin),
            };
        }
        let mut c = environment::child(&self.mpirun);
        c.envs(MPI_ENV)
            .arg("-np")
            .arg(setting.ranks().to_string())
            .args(MPI_ARGS);
        if let Some(time) = &self.time {
            // Each rank: time -o PREFIX.RANK lse-deform ARGS.
            c.args([
                "/bin/sh",
                "-c",
                "t=\"$0\"; p=\"$1\"; shift; exec \"$t\" -f %M -o \"$p.$OMPI_COMM_WORLD_RANK\" \"$@\"",
            ])
            .arg(time)
            .arg(rss);
        }
        c.arg(&self.bin);
        c
    }
}

/// `PREFIX.RANK`.
fn rank_file(prefix: &Path, rank: usize) -> PathBuf {
    let mut s = prefix.as_os_str().to_owned();
    s.push(format!(".{rank}"));
    PathBuf::from(s)
}

/// The peak resident set GNU time wrote with `-f %M` (KiB, on the last
/// line: a failed command's status line comes first), in bytes.
fn parse_time_kib(text: &str) -> Option<u64> {
    let kib: u64 = text
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())?
        .trim()
        .parse()
        .ok()?;
    Some(kib * 1024)
}

/// Runs `tools.bin ARGS` (as `what`), or the last line of its error.
fn run_cli(tools: &Tools, args: &[&std::ffi::OsStr], what: &str) -> Result<(), String> {
    let out = environment::child(&tools.bin)
        .args(args)
        .output()
        .map_err(|e| format!("{what}: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!("{what} failed: {}", environment::failure(&out)))
    }
}

/// What one run left: its report and each process's peak resident set.
struct Run {
    report: Value,
    rss: Vec<u64>,
    output: PathBuf,
}

/// `lse-deform deform` of `case` with `scene` in `setting`.
fn deform(tools: &Tools, case: &Case, scene: &Path, setting: Setting) -> Result<Run, String> {
    let stem = tools
        .scratch
        .join(format!("{}-{}", case.name, setting.stem()));
    let output = stem.with_extension("ply");
    let report = stem.with_extension("json");
    let rss = stem.with_extension("rss");
    let mut c = tools.command(setting, &rss);
    c.arg("deform")
        .arg(&case.path)
        .arg("-c")
        .arg(scene)
        .arg("-o")
        .arg(&output)
        .arg("--report")
        .arg(&report);
    if setting != Setting::Faer {
        c.args(["--factor", "mumps"]);
    }
    if setting == Setting::OutOfCore {
        let dir = tools.scratch.join("out-of-core");
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        c.arg("--out-of-core").arg(dir);
    }
    let out = c
        .output()
        .map_err(|e| format!("{}: {e}", setting.label()))?;
    if !out.status.success() {
        return Err(format!(
            "{} failed: {}",
            setting.label(),
            environment::failure(&out)
        ));
    }
    let text = std::fs::read_to_string(&report).map_err(|e| format!("report: {e}"))?;
    let report: Value = serde_json::from_str(&text).map_err(|e| format!("report: {e}"))?;
    let rss = match &tools.time {
        Some(_) => (0..setting.ranks())
            .filter_map(|r| std::fs::read_to_string(rank_file(&rss, r)).ok())
            .filter_map(|t| parse_time_kib(&t))
            .collect(),
        None => Vec::new(),
    };
    Ok(Run {
        report,
        rss,
        output,
    })
}

/// The numbers of a JSON array of integers.
fn integers(v: Option<&Value>) -> Vec<u64> {
    v.and_then(Value::as_array)
        .map(|a| a.iter().filter_map(Value::as_u64).collect())
        .unwrap_or_default()
}

/// The row of a run (or of its failure).
fn row_of(case: &Case, setting: Setting, run: &Result<Run, String>) -> Row {
    let r = run.as_ref().ok().map(|r| &r.report);
    let f = |pointer: &str| r.and_then(|r| r.pointer(pointer)).and_then(Value::as_f64);
    Row {
        mesh: case.name.clone(),
        vertices: r
            .and_then(|r| r.pointer("/vertices"))
            .and_then(Value::as_u64)
            .unwrap_or(0) as usize,
        setting: setting.label(),
        ranks: setting.ranks(),
        mumps: setting != Setting::Faer,
        out_of_core: setting == Setting::OutOfCore,
        analysis_s: f("/timings_s/symbolic"),
        factorisation_s: f("/timings_s/numeric"),
        solve_s: f("/timings_s/solve"),
        factor_entries: r
            .and_then(|r| r.pointer("/nnz/factor"))
            .and_then(Value::as_u64),
        factor_entries_per_rank: integers(
            r.and_then(|r| r.pointer("/mumps/factor_entries_per_rank")),
        ),
        peak_bytes_per_rank: integers(r.and_then(|r| r.pointer("/mumps/peak_bytes_per_rank"))),
        peak_rss_per_rank: run.as_ref().map(|r| r.rss.clone()).unwrap_or_default(),
        ordering: r
            .and_then(|r| r.pointer("/mumps/ordering"))
            .and_then(Value::as_str)
            .map(str::to_string),
        max_difference_to_faer: None,
        status: match run {
            Ok(_) => "ok".into(),
            Err(e) => format!("failed: {e}"),
        },
    }
}

/// The largest vertex distance between two meshes of the same vertices
/// over `diagonal`.
fn max_difference(a: &Path, b: &Path, diagonal: f64) -> Result<f64, AnyError> {
    let a = read_mesh(a, lse_deform::limits::MemoryBudget::default())?.mesh;
    let b = read_mesh(b, lse_deform::limits::MemoryBudget::default())?.mesh;
    if a.n_vertices() != b.n_vertices() {
        return Err("the two results differ in their vertex count".into());
    }
    let d = a
        .positions()
        .iter()
        .zip(b.positions())
        .map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    Ok(d / diagonal)
}

/// Every setting on one mesh: the scene, the runs, their rows (with the
/// difference to the faer result); the scratch files are removed after.
fn measure_case(tools: &Tools, case: &Case, notes: &mut Vec<String>) -> Vec<Row> {
    let scene = tools.scratch.join(format!("{}-scene.json", case.name));
    let made = run_cli(
        tools,
        &[
            "scene".as_ref(),
            case.path.as_os_str(),
            "-o".as_ref(),
            scene.as_os_str(),
        ],
        "lse-deform scene",
    );
    if let Err(e) = made {
        notes.push(format!("{}: {e}", case.name));
        return Vec::new();
    }
    let runs: Vec<(Setting, Result<Run, String>)> = Setting::ALL
        .into_iter()
        .map(|s| (s, deform(tools, case, &scene, s)))
        .collect();
    let diagonal = read_mesh(&case.path, lse_deform::limits::MemoryBudget::default())
        .map(|m| m.mesh.bbox_diagonal());
    if let Err(e) = &diagonal {
        notes.push(format!("{}: reading the rest mesh: {e}", case.name));
    }
    let faer = runs
        .iter()
        .find(|(s, _)| *s == Setting::Faer)
        .and_then(|(_, r)| r.as_ref().ok());
    let mut rows = Vec::new();
    for (setting, run) in &runs {
        let mut row = row_of(case, *setting, run);
        if let (Some(faer), Ok(run), Ok(diagonal)) = (faer, run, &diagonal)
            && *setting != Setting::Faer
        {
            match max_difference(&faer.output, &run.output, *diagonal) {
                Ok(d) => row.max_difference_to_faer = Some(d),
                Err(e) => notes.push(format!(
                    "{} / {}: comparing with faer: {e}",
                    case.name, row.setting
                )),
            }
        }
        if let Err(e) = run {
            notes.push(format!("{} / {}: {e}", case.name, row.setting));
        }
        rows.push(row);
    }
    for (_, run) in runs.into_iter().filter_map(|(s, r)| r.ok().map(|r| (s, r))) {
        let _ = std::fs::remove_file(&run.output);
    }
    rows
}

/// `lse-deform generate KIND --vertices N` into the scratch directory,
/// named by the vertex count the generator chose.
fn generated(ctx: &Context, tools: &Tools, kind: &str, vertices: usize) -> Result<Case, AnyError> {
    let path = tools.scratch.join(format!("{kind}-{vertices}.ply"));
    let (n, seed) = (vertices.to_string(), ctx.seed.to_string());
    run_cli(
        tools,
        &[
            "generate".as_ref(),
            kind.as_ref(),
            "--vertices".as_ref(),
            n.as_ref(),
            "--seed".as_ref(),
            seed.as_ref(),
            "-o".as_ref(),
            path.as_os_str(),
        ],
        "lse-deform generate",
    )?;
    let made = read_mesh(&path, lse_deform::limits::MemoryBudget::default())?
        .mesh
        .n_vertices();
    Ok(Case {
        name: format!("{kind}-{}k", (made + 500) / 1000),
        path,
        source: format!(
            "generated by `lse-deform generate {kind} --vertices {vertices} --seed {}` ({made} vertices)",
            ctx.seed
        ),
    })
}

/// The meshes: with `--quick` two small generated icospheres; else the Bunny (a
/// generated 35k bumpy sphere without it), Igea 537k (left out without
/// it) and a generated icosphere of about 650k vertices.
fn cases(ctx: &Context, tools: &Tools, notes: &mut Vec<String>) -> Result<Vec<Case>, AnyError> {
    if ctx.quick {
        return Ok(vec![
            generated(ctx, tools, "icosphere", 2_500)?,
            generated(ctx, tools, "icosphere", 10_000)?,
        ]);
    }
    let mut cases = Vec::new();
    match ctx.mesh_file("bunny-35k-stanford.obj") {
        Some(path) => cases.push(Case {
            name: "bunny-35k".into(),
            path: path.to_path_buf(),
            source: "bunny-35k-stanford.obj of --mesh-dir".into(),
        }),
        None => cases.push(generated(ctx, tools, "bumpy-sphere", 35_000)?),
    }
    match ctx.mesh_file("igea-537k-subdiv.obj.gz") {
        Some(path) => cases.push(Case {
            name: "igea-537k".into(),
            path: path.to_path_buf(),
            source: "igea-537k-subdiv.obj.gz of --mesh-dir".into(),
        }),
        None => notes.push("Igea 537k left out: no igea-537k-subdiv.obj.gz among the meshes (give --mesh-dir ../shared/meshes)".into()),
    }
    cases.push(generated(ctx, tools, "icosphere", 650_000)?);
    Ok(cases)
}

// ---------------------------------------------------------------------------
// The projection.

/// `n·log₂n`.
fn n_log_n(n: f64) -> f64 {
    n * n.log2()
}

/// The least-squares `c` of `y ≈ c·n·log₂n` over `(n, y)` (through the
/// origin: `c = Σ x·y / Σ x²`, `x = n·log₂n`); `None` without points.
fn fit_n_log_n(points: &[(f64, f64)]) -> Option<f64> {
    let (xy, xx) = points.iter().fold((0.0, 0.0), |(xy, xx), &(n, y)| {
        let x = n_log_n(n);
        (xy + x * y, xx + x * x)
    });
    (xx > 0.0).then(|| xy / xx)
}

/// The `n` with `c·n·log₂n = y` (fixed point `n = y / (c·log₂n)`, which
/// converges for `n ≥ 2`); `None` unless `c, y > 0`.
fn invert_n_log_n(c: f64, y: f64) -> Option<f64> {
    if c <= 0.0 || y <= 0.0 || !c.is_finite() || !y.is_finite() {
        return None;
    }
    let target = y / c;
    let mut n = target.max(4.0);
    for _ in 0..200 {
        n = target / n.log2().max(1.0);
    }
    Some(n)
}

/// The largest rank's share over the mean share (1 for an even split).
fn imbalance(per_rank: &[u64]) -> Option<f64> {
    let total: u64 = per_rank.iter().sum();
    let max = *per_rank.iter().max()?;
    (total > 0).then(|| max as f64 * per_rank.len() as f64 / total as f64)
}

/// The model of the projection, from the measured runs.
#[derive(Debug, Clone, Serialize)]
struct Model {
    /// `c` of `nnz(L) ≈ c·n·log₂n` (one-rank MUMPS runs, in core).
    c_factor_entries: f64,
    /// `c` of MUMPS's bytes (sum over ranks) `≈ c·n·log₂n`.
    c_mumps_bytes: f64,
    /// The mesh of the 2-rank run the imbalance factors come from.
    imbalance_mesh: String,
    /// The factor entries of the largest rank of the 2-rank run over half
    /// the 1-rank total of the same mesh: [`Split::unevenness`] ×
    /// [`Split::growth`], what the projection multiplies `total / ranks`
    /// by.
    imbalance_entries: f64,
    /// The same of MUMPS's bytes.
    imbalance_bytes: f64,
    /// The two parts of `imbalance_entries`.
    split_entries: Split,
    /// The two parts of `imbalance_bytes`.
    split_bytes: Split,
    /// Rank 0's peak resident set beyond rank 1's, per vertex (2 ranks,
    /// the same mesh): the centralised input and rank 0's own pipeline.
    rank0_extra_bytes_per_vertex: Option<f64>,
    /// The report's `nnz.factor` (MUMPS's `INFOG(29)`) over the sum of the
    /// ranks' `INFO(27)` on the largest one-rank run: 1 when the ranks'
    /// shares add up to the total (a check of what is read); the fit is of
    /// the second (what the ranks store).
    infog29_over_info29: Option<f64>,
}

/// How a quantity split between the two ranks of a run.
#[derive(Debug, Clone, Copy, Serialize)]
struct Split {
    /// Largest rank over the mean of the two ranks (1: even).
    unevenness: f64,
    /// The two ranks' total over the one-rank total (1: nothing added by
    /// splitting).
    growth: f64,
}

impl Split {
    /// The split of `two` (per rank, 2 ranks) against `one` (1 rank).
    fn of(two: &[u64], one: &[u64]) -> Option<Split> {
        let one: u64 = one.iter().sum();
        (one > 0).then_some(())?;
        Some(Split {
            unevenness: imbalance(two)?,
            growth: two.iter().sum::<u64>() as f64 / one as f64,
        })
    }

    /// Largest rank over half the one-rank total.
    fn factor(self) -> f64 {
        self.unevenness * self.growth
    }
}

/// One projected configuration.
#[derive(Debug, Clone, Serialize)]
struct Projection {
    vertices: f64,
    ranks: usize,
    factor_entries_total: f64,
    factor_entries_per_rank: f64,
    mumps_bytes_per_rank: f64,
    /// Rank 0: its MUMPS bytes plus the extra of the centralised input.
    rank0_bytes: Option<f64>,
}

/// The rows of one-rank in-core MUMPS runs as `(n, y)` points.
fn one_rank_points(rows: &[Row], y: fn(&Row) -> u64) -> Vec<(f64, f64)> {
    rows.iter()
        .filter(|r| r.mumps && r.ranks == 1 && !r.out_of_core && r.status == "ok")
        .map(|r| (r.vertices as f64, y(r) as f64))
        .filter(|&(_, y)| y > 0.0)
        .collect()
}

/// The model, from the rows; `None` without a one-rank and a two-rank run
/// of the same mesh.
fn model(rows: &[Row]) -> Option<Model> {
    let entries = one_rank_points(rows, |r| r.factor_entries_per_rank.iter().sum());
    let bytes = one_rank_points(rows, |r| r.peak_bytes_per_rank.iter().sum());
    let two = rows
        .iter()
        .filter(|r| r.mumps && r.ranks == 2 && r.status == "ok")
        .max_by_key(|r| r.vertices)?;
    let one = rows.iter().find(|r| {
        r.mumps && r.ranks == 1 && !r.out_of_core && r.status == "ok" && r.mesh == two.mesh
    })?;
    let split_entries = Split::of(&two.factor_entries_per_rank, &one.factor_entries_per_rank)?;
    let split_bytes = Split::of(&two.peak_bytes_per_rank, &one.peak_bytes_per_rank)?;
    let rank0_extra = match two.peak_rss_per_rank.as_slice() {
        [r0, r1] => Some(r0.saturating_sub(*r1) as f64 / two.vertices as f64),
        _ => None,
    };
    let infog29_over_info29 = rows
        .iter()
        .filter(|r| r.mumps && r.ranks == 1 && !r.out_of_core && r.status == "ok")
        .max_by_key(|r| r.vertices)
        .and_then(|r| {
            let sum: u64 = r.factor_entries_per_rank.iter().sum();
            r.factor_entries
                .filter(|_| sum > 0)
                .map(|e| e as f64 / sum as f64)
        });
    Some(Model {
        infog29_over_info29,
        c_factor_entries: fit_n_log_n(&entries)?,
        c_mumps_bytes: fit_n_log_n(&bytes)?,
        imbalance_mesh: two.mesh.clone(),
        imbalance_entries: split_entries.factor(),
        imbalance_bytes: split_bytes.factor(),
        split_entries,
        split_bytes,
        rank0_extra_bytes_per_vertex: rank0_extra,
    })
}

/// The projected vertex counts and rank counts.
const PROJECTED_VERTICES: [f64; 2] = [20e6, 100e6];
const PROJECTED_RANKS: [usize; 2] = [8, 64];

/// The model at 20 M and 100 M vertices on 8 and 64 ranks: totals split
/// evenly, times the 2-rank imbalance; rank 0 plus its extra.
fn project(m: &Model) -> Vec<Projection> {
    let mut out = Vec::new();
    for n in PROJECTED_VERTICES {
        for p in PROJECTED_RANKS {
            let total = m.c_factor_entries * n_log_n(n);
            let bytes = m.c_mumps_bytes * n_log_n(n) / p as f64 * m.imbalance_bytes;
            out.push(Projection {
                vertices: n,
                ranks: p,
                factor_entries_total: total,
                factor_entries_per_rank: total / p as f64 * m.imbalance_entries,
                mumps_bytes_per_rank: bytes,
                rank0_bytes: m.rank0_extra_bytes_per_vertex.map(|e| bytes + e * n),
            });
        }
    }
    out
}

/// The largest mesh that fits in memory, per setting: the peak resident
/// set of rank 0 fitted as `r·n·log₂n` over the meshes, solved for the
/// machine's memory. Extrapolated, not measured.
#[derive(Debug, Clone, Serialize)]
struct Limit {
    setting: String,
    /// Rank 0's peak resident set on the largest mesh, bytes.
    largest_mesh_rss: u64,
    largest_mesh: String,
    largest_mesh_vertices: usize,
    /// `r` of `RSS ≈ r·n·log₂n`.
    r: f64,
    /// The `n` with `r·n·log₂n` = the machine's memory.
    extrapolated_vertices: Option<f64>,
}

/// [`Limit`] of the one-process settings (faer, MUMPS in and out of core).
fn limits(rows: &[Row], memory_bytes: f64) -> Vec<Limit> {
    let mut out = Vec::new();
    for setting in [
        Setting::Faer,
        Setting::Mumps { ranks: 1 },
        Setting::OutOfCore,
    ] {
        let label = setting.label();
        let ok: Vec<&Row> = rows
            .iter()
            .filter(|r| r.setting == label && r.status == "ok" && !r.peak_rss_per_rank.is_empty())
            .collect();
        let points: Vec<(f64, f64)> = ok
            .iter()
            .map(|r| (r.vertices as f64, r.peak_rss_per_rank[0] as f64))
            .collect();
        let (Some(largest), Some(r)) = (ok.iter().max_by_key(|r| r.vertices), fit_n_log_n(&points))
        else {
            continue;
        };
        out.push(Limit {
            setting: label,
            largest_mesh_rss: largest.peak_rss_per_rank[0],
            largest_mesh: largest.mesh.clone(),
            largest_mesh_vertices: largest.vertices,
            r,
            extrapolated_vertices: invert_n_log_n(r, memory_bytes),
        });
    }
    out
}

// ---------------------------------------------------------------------------
// Data, figures, section.

/// A list of integers as one CSV cell, `a;b`.
fn joined(v: &[u64]) -> String {
    v.iter().map(u64::to_string).collect::<Vec<_>>().join(";")
}

/// `distributed.csv` and `distributed.json` (rows, model, projection,
/// limits).
fn write_data(
    ctx: &Context,
    dir: &Path,
    rows: &[Row],
    model: Option<&Model>,
    projection: &[Projection],
    limits: &[Limit],
) -> Result<(), AnyError> {
    let header = [
        "mesh",
        "vertices",
        "setting",
        "ranks",
        "analysis_s",
        "factorisation_s",
        "solve_s",
        "factor_entries",
        "factor_entries_per_rank",
        "peak_bytes_per_rank",
        "peak_rss_per_rank",
        "ordering",
        "max_difference_to_faer",
        "status",
    ];
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.mesh.clone(),
                r.vertices.to_string(),
                r.setting.clone(),
                r.ranks.to_string(),
                opt(r.analysis_s),
                opt(r.factorisation_s),
                opt(r.solve_s),
                r.factor_entries.map_or(String::new(), |v| v.to_string()),
                joined(&r.factor_entries_per_rank),
                joined(&r.peak_bytes_per_rank),
                joined(&r.peak_rss_per_rank),
                r.ordering.clone().unwrap_or_default(),
                opt(r.max_difference_to_faer),
                r.status.clone(),
            ]
        })
        .collect();
    ctx.write_csv(&dir.join("distributed.csv"), &header, &cells)?;
    let doc = serde_json::json!({
        "runs": rows, "model": model, "projection": projection, "limits": limits,
    });
    ctx.write_json(&dir.join("distributed.json"), &doc)
}

/// One stacked-bar figure of a per-rank quantity: a bar per mesh and rank
/// count, a segment per rank. `(stem, drawn)`.
fn per_rank_figure(
    dir: &Path,
    rows: &[Row],
    stem: &str,
    title: &str,
    unit: (&str, f64),
    values: fn(&Row) -> &[u64],
    notes: &mut Vec<String>,
) -> Result<Option<String>, AnyError> {
    let categories: Vec<Category> = rows
        .iter()
        .filter(|r| r.mumps && !r.out_of_core && !values(r).is_empty())
        .map(|r| {
            let v = values(r);
            Category {
                name: format!(
                    "{} / {} rank{}",
                    r.mesh,
                    r.ranks,
                    if r.ranks == 1 { "" } else { "s" }
                ),
                values: (0..2)
                    .map(|k| v.get(k).map_or(0.0, |&x| x as f64 / unit.1))
                    .collect(),
            }
        })
        .collect();
    if categories.is_empty() {
        notes.push(format!("no bar of '{title}' could be drawn"));
        return Ok(None);
    }
    let n_bars = categories.len() as u32;
    let spec = StackedBars {
        title: title.into(),
        value_label: unit.0.into(),
        segments: vec!["rank 0".into(), "rank 1".into()],
        categories,
        total_suffix: Some(String::new()),
        legend: LegendPosition::Auto,
    };
    let out = Output::new(dir.join(stem)).with_size(960, 200 + 44 * n_bars);
    note_drawn(&plot::stacked_bars(&spec, &out)?, notes);
    Ok(Some(stem.to_string()))
}

/// The figures: per-rank factor entries and MUMPS memory, 1 against 2
/// ranks.
fn figures(dir: &Path, rows: &[Row], notes: &mut Vec<String>) -> Result<Vec<String>, AnyError> {
    let mut stems = Vec::new();
    stems.extend(per_rank_figure(
        dir,
        rows,
        "per_rank_factor",
        "MUMPS factor entries per rank (INFO(27)), 1 and 2 ranks",
        ("factor entries (millions)", 1e6),
        |r| &r.factor_entries_per_rank,
        notes,
    )?);
    stems.extend(per_rank_figure(
        dir,
        rows,
        "per_rank_memory",
        "MUMPS memory per rank (INFO(22)), 1 and 2 ranks",
        ("MiB", (1u64 << 20) as f64),
        |r| &r.peak_bytes_per_rank,
        notes,
    )?);
    Ok(stems)
}

/// Bytes in MiB, for the tables.
fn mib(bytes: f64) -> String {
    format!("{:.0}", bytes / (1u64 << 20) as f64)
}

/// Bytes in GiB, for the projection.
fn gib(bytes: f64) -> String {
    format!("{:.1} GiB", bytes / (1u64 << 30) as f64)
}

/// A per-rank list as `a / b` with `f` applied.
fn per_rank(v: &[u64], f: impl Fn(f64) -> String) -> String {
    if v.is_empty() {
        return "—".into();
    }
    v.iter()
        .map(|&x| f(x as f64))
        .collect::<Vec<_>>()
        .join(" / ")
}

/// The measured table.
fn runs_table(rows: &[Row]) -> String {
    let header = [
        "mesh",
        "vertices",
        "setting",
        "analysis",
        "factorisation",
        "solve",
        "factor entries per rank (M)",
        "MUMPS peak per rank (MiB)",
        "peak RSS per rank (MiB)",
        "max difference to faer (× diagonal)",
        "ordering",
    ];
    let t = |v: Option<f64>| v.map_or("—".into(), fmt_time);
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let entries = if r.mumps {
                per_rank(&r.factor_entries_per_rank, |x| format!("{:.2}", x / 1e6))
            } else {
                r.factor_entries
                    .map_or("—".into(), |e| format!("{:.2} (faer)", e as f64 / 1e6))
            };
            let mut cells = vec![
                r.mesh.clone(),
                r.vertices.to_string(),
                r.setting.clone(),
                t(r.analysis_s),
                t(r.factorisation_s),
                t(r.solve_s),
                entries,
                per_rank(&r.peak_bytes_per_rank, mib),
                per_rank(&r.peak_rss_per_rank, mib),
                r.max_difference_to_faer
                    .map_or("—".into(), |d| format!("{d:.1e}")),
                r.ordering.clone().unwrap_or_else(|| "—".into()),
            ];
            if r.status != "ok" {
                cells[3] = r.status.replace('|', "/");
            }
            cells
        })
        .collect();
    markdown_table(&header, &cells)
}

/// The projection's paragraph and table.
fn projection_text(m: &Model, projection: &[Projection]) -> String {
    let mut s = String::new();
    let extra = m.rank0_extra_bytes_per_vertex.map_or(
        "not measured (no peak resident sets: `/usr/bin/time` is missing)".to_string(),
        |e| format!("{e:.0} bytes per vertex"),
    );
    let _ = writeln!(
        s,
        "**Projection (not a measurement).** A nested-dissection ordering of a surface mesh (a planar-like graph) fills its Cholesky factor with O(n log n) entries, \
         so the one-rank in-core runs above are fitted (least squares through the origin) with \
         **nnz(L) ≈ c·n·log₂n, c = {:.3}** (nnz(L) = the ranks' INFO(27) summed: what they store{}), and MUMPS's memory summed over ranks (INFO(22)) with **bytes ≈ c_b·n·log₂n, c_b = {:.1}**. \
         Per rank = total / ranks × the imbalance factor measured on the 2-rank run of {}: its largest rank over half the 1-rank total of the same mesh, \
         {:.3} for the factor entries ({:.3} unevenness between the two ranks × {:.3} growth of the total when split) and {:.3} for the memory ({:.3} × {:.3}). \
         This assumes an even split up to that factor on 8 and 64 ranks; MUMPS's tree mapping does not promise it, and the growth of the total when split is likely to be larger with more ranks, \
         so the per-rank figures are if anything optimistic. \
         Rank 0 also holds the centralised input (mesh, assembled matrix, the null-space pipeline before MUMPS: `ICNTL(18) = 0`, sequential analysis `ICNTL(28) = 1`): \
         its peak resident set beyond rank 1's on that run, {extra}, is added to rank 0.\n",
        m.c_factor_entries,
        m.infog29_over_info29.map_or(String::new(), |r| format!(
            "; the report's `nnz.factor`, MUMPS's INFOG(29), is {r:.2} × that on the largest one-rank run"
        )),
        m.c_mumps_bytes,
        m.imbalance_mesh,
        m.imbalance_entries,
        m.split_entries.unevenness,
        m.split_entries.growth,
        m.imbalance_bytes,
        m.split_bytes.unevenness,
        m.split_bytes.growth
    );
    let cells: Vec<Vec<String>> = projection
        .iter()
        .map(|p| {
            vec![
                format!("{:.0} M", p.vertices / 1e6),
                p.ranks.to_string(),
                format!("{:.2e}", p.factor_entries_total),
                format!("{:.2e}", p.factor_entries_per_rank),
                gib(p.mumps_bytes_per_rank),
                p.rank0_bytes.map_or("—".into(), gib),
            ]
        })
        .collect();
    s.push_str(&markdown_table(
        &[
            "vertices",
            "ranks",
            "nnz(L) total",
            "nnz(L) per rank",
            "MUMPS memory per rank",
            "rank 0 with the centralised input",
        ],
        &cells,
    ));
    s
}

/// The extrapolated limits' paragraph and table.
fn limits_text(limits: &[Limit], memory_gib: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\n**Largest mesh that fits in this machine's {memory_gib:.0} GiB (extrapolated, not measured).** \
         The peak resident set of the one process of each setting, fitted over the meshes above as RSS ≈ r·n·log₂n and solved for r·n·log₂n = {memory_gib:.0} GiB. \
         Out of core the factor is in files and what stays in memory grows more nearly like n, so the same form understates its limit; \
         the limit assumes the machine's whole memory is free.\n"
    );
    let cells: Vec<Vec<String>> = limits
        .iter()
        .map(|l| {
            vec![
                l.setting.clone(),
                format!("{} ({} vertices)", l.largest_mesh, l.largest_mesh_vertices),
                format!("{} MiB", mib(l.largest_mesh_rss as f64)),
                format!("{:.1}", l.r),
                l.extrapolated_vertices
                    .map_or("—".into(), |n| format!("≈ {:.1} M vertices", n / 1e6)),
            ]
        })
        .collect();
    s.push_str(&markdown_table(
        &[
            "setting",
            "largest mesh measured",
            "its peak RSS",
            "r (bytes)",
            "extrapolated limit",
        ],
        &cells,
    ));
    s
}

/// The section.
fn section(ctx: &Context, tables: &Tables, figures: &[String], notes: &[String]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "The `lse-deform` command-line tool (release, `--features mumps`) run on each mesh with the scene `lse-deform scene` writes for it, \
         once per setting: `deform` with faer-auto without MPI (the reference), and `deform --factor mumps` under `mpirun` with 1 and 2 ranks in core and with 1 rank out of core (`--out-of-core`). \
         Rank 0 reads, assembles and drives; the other rank serves its MUMPS commands. \
         Analysis, factorisation and solve are the report's `timings_s.symbolic` (MUMPS: JOB = 1), `numeric` (JOB = 2) and `solve` (JOB = 3 plus the library's checks); \
         the factor entries and MUMPS's memory per rank are the report's `mumps.factor_entries_per_rank` (INFO(27)) and `peak_bytes_per_rank` (INFO(22)); \
         the peak resident set of each process is GNU time's `%M`. The difference to faer is the largest vertex distance between the two deformed meshes over the rest mesh's bounding-box diagonal. \
         One run per setting (no repetitions): the times carry the noise of a shared machine.\n"
    );
    let _ = writeln!(s, "Meshes: {}.\n", tables.sources.join("; "));
    s.push_str(&ctx.regenerate(NAME));
    s.push_str(&runs_table(&tables.rows));
    let _ = writeln!(
        s,
        "\n**What two ranks on this machine show.** Both ranks run on the {} cores of one machine and talk over TCP on the loopback interface: \
         the runs show that the distributed path gives the same deformation as faer (the last column) and how the factor and MUMPS's memory split between the ranks \
         (the figures), not a speed-up across machines — two ranks share one memory bus (and the cores with whatever else runs), and nothing here measures a network.\n",
        ctx.machine.cores
    );
    for stem in figures {
        let what = if stem == "per_rank_factor" {
            "MUMPS's factor entries per rank (INFO(27), millions)"
        } else {
            "MUMPS's memory per rank (INFO(22), MiB)"
        };
        let _ = writeln!(
            s,
            "\n**Figure.** {what}: one bar per mesh and rank count, one segment per rank, the total at the end. \
             Compare a mesh's 2-rank bar with its 1-rank bar: how evenly the two ranks share, and what the split adds in total.\n\n{}",
            link(NAME, stem)
        );
    }
    match &tables.model {
        Some(m) => {
            s.push('\n');
            s.push_str(&projection_text(m, &tables.projection));
        }
        None => s.push_str("\nNo projection: it needs a one-rank and a two-rank MUMPS run.\n"),
    }
    if !tables.limits.is_empty() {
        s.push_str(&limits_text(&tables.limits, ctx.machine.memory_gib));
    }
    s.push_str(&ctx.closing(
        notes,
        &format!("Data: [`{NAME}/distributed.csv`]({NAME}/distributed.csv), [`{NAME}/distributed.json`]({NAME}/distributed.json) (with the model, the projection and the limits)."),
    ));
    s
}

/// What the section shows.
struct Tables {
    /// Each mesh's name and origin.
    sources: Vec<String>,
    rows: Vec<Row>,
    model: Option<Model>,
    projection: Vec<Projection>,
    limits: Vec<Limit>,
}

/// The section of a run that measured nothing, saying why.
fn not_measured(ctx: &Context, why: &str) -> Result<Summary, AnyError> {
    let s = format!(
        "MUMPS on one and two MPI ranks, the per-rank factor and memory, and a projection to larger meshes: **not measured**, {why}. No number of this section is invented.\n\n{}",
        ctx.regenerate(NAME)
    );
    ctx.write_section(NAME, &s)?;
    Ok(Summary::skipped(format!("not measured: {why}")))
}

/// The programs, or why the section cannot run.
fn tools() -> Result<Tools, String> {
    if !cfg!(feature = "mumps") {
        return Err("MUMPS is not in this build (`--features mumps`)".into());
    }
    let mpirun = environment::mpirun()?;
    let bin = environment::cli_binary()?;
    let scratch = std::env::temp_dir().join(format!("lse-deform-{NAME}-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).map_err(|e| format!("{}: {e}", scratch.display()))?;
    Ok(Tools {
        bin,
        mpirun,
        time: environment::gnu_time(),
        scratch,
    })
}

/// The headline: the 2-rank split and the difference to faer.
fn headline(rows: &[Row]) -> String {
    let two = rows
        .iter()
        .filter(|r| r.mumps && r.ranks == 2 && r.status == "ok")
        .max_by_key(|r| r.vertices);
    let worst = rows
        .iter()
        .filter_map(|r| r.max_difference_to_faer)
        .fold(0.0, f64::max);
    match two.and_then(|r| imbalance(&r.factor_entries_per_rank).map(|i| (r, i))) {
        Some((r, i)) => format!(
            "{} ({} vertices) on 2 ranks: factor {} M entries per rank (imbalance {i:.2}); max difference to faer {worst:.1e} of the diagonal",
            r.mesh,
            r.vertices,
            per_rank(&r.factor_entries_per_rank, |x| format!("{:.1}", x / 1e6))
        ),
        None => "no 2-rank run succeeded".into(),
    }
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let dir = ctx.dir(NAME)?;
    let tools = match tools() {
        Ok(t) => t,
        Err(why) => return not_measured(ctx, &why),
    };
    let mut notes = Vec::new();
    if tools.time.is_none() {
        notes.push(
            "no `/usr/bin/time`: the peak resident sets (and rank 0's extra) are not measured"
                .into(),
        );
    }
    let outcome = cases(ctx, &tools, &mut notes).map(|cases| {
        let bar = ctx.bar(cases.len(), NAME);
        let (mut rows, mut sources) = (Vec::new(), Vec::new());
        for case in &cases {
            bar.set_message(format!("{NAME}: {}", case.name));
            sources.push(format!("{} ({})", case.name, case.source));
            rows.extend(measure_case(&tools, case, &mut notes));
            bar.inc(1);
        }
        bar.finish_and_clear();
        (rows, sources)
    });
    let _ = std::fs::remove_dir_all(&tools.scratch);
    let (rows, sources) = outcome?;
    if !rows.iter().any(|r| r.mumps && r.status == "ok") {
        let why = notes
            .iter()
            .rev()
            .find(|n| n.contains("failed"))
            .cloned()
            .unwrap_or_else(|| "no mesh was measured".into());
        return Err(format!("no MUMPS run succeeded; the last failure: {why}").into());
    }
    let model = model(&rows);
    let tables = Tables {
        projection: model.as_ref().map(project).unwrap_or_default(),
        limits: limits(&rows, ctx.machine.memory_gib * (1u64 << 30) as f64),
        model,
        rows,
        sources,
    };
    write_data(
        ctx,
        &dir,
        &tables.rows,
        tables.model.as_ref(),
        &tables.projection,
        &tables.limits,
    )?;
    let figures = figures(&dir, &tables.rows, &mut notes)?;
    ctx.write_section(NAME, &section(ctx, &tables, &figures, &notes))?;
    Ok(Summary::measured(headline(&tables.rows)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_n_log_n_fit_recovers_its_constant_and_inverts() {
        let points: Vec<(f64, f64)> = [1e4, 3e4, 5e5]
            .iter()
            .map(|&n| (n, 2.5 * n_log_n(n)))
            .collect();
        let c = fit_n_log_n(&points).unwrap();
        assert!((c - 2.5).abs() < 1e-12, "{c}");
        let n = invert_n_log_n(c, 2.5 * n_log_n(7.0e6)).unwrap();
        assert!((n / 7.0e6 - 1.0).abs() < 1e-9, "{n}");
        assert_eq!(fit_n_log_n(&[]), None);
        assert_eq!(invert_n_log_n(0.0, 1.0), None);
    }

    #[test]
    fn imbalance_is_the_largest_share_over_the_mean() {
        assert_eq!(imbalance(&[50, 50]), Some(1.0));
        assert_eq!(imbalance(&[60, 40]), Some(1.2));
        assert_eq!(imbalance(&[]), None);
        assert_eq!(imbalance(&[0, 0]), None);
    }

    #[test]
    fn a_split_is_unevenness_times_growth() {
        let s = Split::of(&[60, 40], &[80]).unwrap();
        assert!((s.unevenness - 1.2).abs() < 1e-12);
        assert!((s.growth - 1.25).abs() < 1e-12);
        // The largest rank (60) over half the one-rank total (40).
        assert!((s.factor() - 1.5).abs() < 1e-12);
        assert!(Split::of(&[1, 1], &[0]).is_none());
    }

    #[test]
    fn gnu_time_output_is_read_from_its_last_line() {
        assert_eq!(parse_time_kib("1234\n"), Some(1234 * 1024));
        assert_eq!(
            parse_time_kib("Command exited with non-zero status 2\n99\n"),
            Some(99 * 1024)
        );
        assert_eq!(parse_time_kib(""), None);
    }

    /// The projection splits the total evenly, applies the imbalance and
    /// adds rank 0's extra per vertex.
    #[test]
    fn the_projection_applies_split_imbalance_and_rank0_extra() {
        let m = Model {
            c_factor_entries: 2.0,
            c_mumps_bytes: 20.0,
            imbalance_mesh: "m".into(),
            imbalance_entries: 1.1,
            imbalance_bytes: 1.2,
            split_entries: Split {
                unevenness: 1.0,
                growth: 1.1,
            },
            split_bytes: Split {
                unevenness: 1.2,
                growth: 1.0,
            },
            rank0_extra_bytes_per_vertex: Some(100.0),
            infog29_over_info29: None,
        };
        let p = project(&m);
        assert_eq!(p.len(), 4);
        let first = &p[0];
        assert_eq!((first.vertices, first.ranks), (20e6, 8));
        let x = n_log_n(20e6);
        assert!((first.factor_entries_per_rank - 2.0 * x / 8.0 * 1.1).abs() < 1e-3 * x);
        let bytes = 20.0 * x / 8.0 * 1.2;
        assert!((first.mumps_bytes_per_rank - bytes).abs() < 1e-6 * bytes);
        assert!((first.rank0_bytes.unwrap() - bytes - 100.0 * 20e6).abs() < 1e-6 * bytes);
    }

    /// Without MUMPS in the build the section measures nothing, says why,
    /// and its status is `skipped`, not `ok` (the summary table used to
    /// print "distributed: ok in 0.0 s — not measured: …").
    #[cfg(not(feature = "mumps"))]
    #[test]
    fn without_mumps_the_section_is_skipped() {
        let out = std::env::temp_dir().join(format!("lse-skipped-{}", std::process::id()));
        let ctx = Context::new(out.clone(), Vec::new(), None, None, true, 1).unwrap();
        let summary = run(&ctx).unwrap();
        let section = std::fs::read_to_string(out.join(NAME).join("section.md")).unwrap();
        let _ = std::fs::remove_dir_all(&out);
        assert!(summary.skipped, "{}", summary.headline);
        assert!(summary.headline.contains("MUMPS is not in this build"));
        assert!(section.contains("**not measured**"), "{section}");
    }
}
