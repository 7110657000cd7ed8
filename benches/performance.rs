//! Criterion benches, one group per performance target
//! (docs/development.md §2).
//!
//! The meshes are generated (a bumpy sphere of about 35k vertices, the size
//! of the Stanford Bunny) unless `LSE_MESH_DIR` names the mesh directory,
//! in which case the Bunny and igea-537k are used. CHOLMOD rows need
//! `--features suitesparse`. Run all with `cargo bench`, one group with e.g.
//! `cargo bench --features suitesparse -- t2_solve`.
//!
//! Each group puts ours and the reference side by side in one run:
//! - `t1_precompute`: our whole precompute vs CHOLMOD's numeric factorisation
//!   (and analysis) of the same reduced normal matrix;
//! - `t2_solve`: our per-frame solve (3 right-hand sides) vs CHOLMOD's solve
//!   vs **the floor itself**: a streaming read of twice the factor's bytes;
//! - `t3_relative`: precompute with 0, 300 and 2000 relative constraints;
//! - `t4_weight_sweep`: the 17-weight penalty sweep vs one numeric
//!   factorisation (× 17 by the reader) and one analysis;
//! - `t5_large`: precompute and solve on the large mesh and its floor;
//! - `t6_setup`: reading an OBJ file and building L and A;
//! - `t7_scaling`: precompute and solve at 1k … 64k vertices;
//! - `refine`: on the Bunny and the Dragon (generated 35k and 50k bumpy
//!   spheres without `LSE_MESH_DIR`), the solve phase alone next to the
//!   refine phase of the default `--refine auto`, both as a later solve
//!   with the factor does it (stopping on the prediction from what earlier
//!   refinements measured, docs/refinement.md §6) and as the first
//!   refinement of a factor (measuring the rounding floor);
//! - `t8_crowded`: set-up, precompute and solve with 20,000 and 200,000
//!   constraints through one vertex (one position constraint repeated;
//!   relative constraints from one hub to 1,000 vertices in turn) on a
//!   10k-vertex sphere: the 200k rows should take at most ~10× the 20k ones
//!   (cost proportional to the input).

use std::hint::black_box;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use faer::Mat;
use faer::sparse::SparseColMat;
use lse_deform::backend::qr::{QrBackend, RankTolerance, SparseGivens};
use lse_deform::backend::spd::{FaerLlt, SpdBackend};
use lse_deform::constraints::ConstraintSet;
use lse_deform::formulation::{NullSpaceQr, PenaltySweep};
use lse_deform::mesh::{Mesh, generate, read_mesh, write_mesh};
use lse_deform::scene::{CrowdedScene, FixedAndHandle, MixedScene};
use lse_deform::solver::LseSolver;
use lse_deform::sparse::NormalPattern;
use lse_deform::{Deformer, LaplacianKind};

fn ours() -> NullSpaceQr {
    NullSpaceQr::new(
        Arc::new(SparseGivens::default()),
        Arc::new(FaerLlt::supernodal()),
    )
}

fn mesh_dir() -> Option<PathBuf> {
    std::env::var_os("LSE_MESH_DIR").map(PathBuf::from)
}

/// The Bunny with `LSE_MESH_DIR`, else a generated 35k-vertex bumpy sphere.
fn main_mesh() -> Mesh {
    if let Some(dir) = mesh_dir()
        && let Ok(m) = read_mesh(
            &dir.join("bunny-35k-stanford.obj"),
            lse_deform::limits::MemoryBudget::default(),
        )
    {
        return m.mesh;
    }
    generate::with_about_vertices(generate::GeneratedKind::BumpySphere, 35_000, 1)
        .expect("generated mesh")
}

/// igea-537k with `LSE_MESH_DIR`, else a generated 250k-vertex bumpy sphere.
fn large_mesh() -> Mesh {
    if let Some(dir) = mesh_dir()
        && let Ok(m) = read_mesh(
            &dir.join("igea-537k-subdiv.obj.gz"),
            lse_deform::limits::MemoryBudget::default(),
        )
    {
        return m.mesh;
    }
    generate::with_about_vertices(generate::GeneratedKind::BumpySphere, 250_000, 1)
        .expect("generated mesh")
}

/// A mesh of `LSE_MESH_DIR` by file name, else a generated bumpy sphere
/// of about `vertices` vertices.
fn named_mesh(file: &str, vertices: usize) -> Mesh {
    if let Some(dir) = mesh_dir()
        && let Ok(m) = read_mesh(&dir.join(file), lse_deform::limits::MemoryBudget::default())
    {
        return m.mesh;
    }
    generate::with_about_vertices(generate::GeneratedKind::BumpySphere, vertices, 1)
        .expect("generated mesh")
}

fn scene(mesh: &Mesh) -> ConstraintSet {
    FixedAndHandle::paper_default(mesh)
        .constraints(mesh)
        .expect("scene")
}

fn deformer(mesh: &Mesh, cs: &ConstraintSet) -> Deformer {
    Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        cs.clone(),
        &lse_deform::SolveOptions::default(),
    )
    .expect("set-up")
}

/// The lower triangle of the reduced normal matrix our precompute factors.
fn reduced_normal(d: &Deformer) -> SparseColMat<usize, f64> {
    let p = d.problem();
    let qr = SparseGivens::default()
        .factor(p.b().as_ref(), RankTolerance::default())
        .expect("qr");
    let aq2 = qr.mul_a_q2(p.a().as_ref());
    NormalPattern::new(aq2.as_ref()).numeric(aq2.as_ref())
}

#[cfg(feature = "suitesparse")]
fn reference() -> Option<Arc<dyn SpdBackend>> {
    Some(Arc::new(lse_deform::backend::spd::Cholmod))
}

#[cfg(not(feature = "suitesparse"))]
fn reference() -> Option<Arc<dyn SpdBackend>> {
    None
}

/// Reads `bytes` bytes twice with an 8-accumulator sum: the bandwidth floor
/// of a solve whose factor has that size, measured rather than assumed.
fn floor_bench(
    c: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    bytes: usize,
) {
    let data: Vec<f64> = (0..bytes / 8).map(|i| (i % 5) as f64).collect();
    c.bench_function("floor: read the factor's bytes twice", |b| {
        b.iter(|| {
            let mut acc = [0.0f64; 8];
            for _ in 0..2 {
                for chunk in data.chunks_exact(8) {
                    for k in 0..8 {
                        acc[k] += chunk[k];
                    }
                }
            }
            black_box(acc)
        })
    });
}

fn t1_precompute(c: &mut Criterion) {
    let mesh = main_mesh();
    let cs = scene(&mesh);
    let mut d = deformer(&mesh, &cs);
    let mut g = c.benchmark_group("t1_precompute");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    let f = ours();
    g.bench_function(
        "ours: QR + preparation + normal + symbolic + numeric",
        |b| {
            b.iter(|| {
                d.refactor_with(&f, &lse_deform::resources::Resources::default())
                    .expect("precompute")
            })
        },
    );
    if let Some(backend) = reference() {
        let normal = reduced_normal(&d);
        let sym = backend.analyze(normal.symbolic()).expect("analyse");
        g.bench_function("cholmod: analyse", |b| {
            b.iter(|| backend.analyze(normal.symbolic()).expect("analyse"))
        });
        g.bench_function("cholmod: factorise", |b| {
            b.iter(|| sym.factorize(normal.as_ref()).expect("factorise"))
        });
    }
    g.finish();
}

fn t2_solve(c: &mut Criterion) {
    let mesh = main_mesh();
    let cs = scene(&mesh);
    let mut d = deformer(&mesh, &cs);
    d.refactor_with(&ours(), &lse_deform::resources::Resources::default())
        .expect("precompute");
    let bytes = d.report().nnz.factor_bytes.unwrap_or(0);
    let mut g = c.benchmark_group("t2_solve");
    g.sample_size(30);
    g.bench_function("ours: y, rhs, two triangular solves, X = Q[y; z]", |b| {
        b.iter(|| d.solve_matrix().expect("solve"))
    });
    if let Some(backend) = reference() {
        let normal = reduced_normal(&d);
        let mut factor = backend
            .analyze(normal.symbolic())
            .and_then(|s| s.factorize(normal.as_ref()))
            .expect("cholmod");
        let rhs = Mat::<f64>::from_fn(normal.ncols(), 3, |i, k| ((i + 3 * k) % 11) as f64);
        let mut x = rhs.clone();
        g.bench_function("cholmod: solve, 3 right-hand sides", |b| {
            b.iter(|| {
                x.copy_from(&rhs);
                factor.solve_in_place(x.as_mut()).expect("solve");
            })
        });
    }
    floor_bench(&mut g, bytes);
    g.finish();
}

fn t3_relative(c: &mut Criterion) {
    let mesh = main_mesh();
    let base = FixedAndHandle::paper_default(&mesh);
    let mut g = c.benchmark_group("t3_relative");
    g.sample_size(10).measurement_time(Duration::from_secs(6));
    let f = ours();
    for relative in [0usize, 300, 2000] {
        let cs = MixedScene {
            base: base.clone(),
            relative,
            edges: 0,
            faces: 0,
            duplicate: false,
            conflict: false,
        }
        .constraints(&mesh)
        .expect("scene");
        let mut d = deformer(&mesh, &cs);
        g.bench_with_input(
            BenchmarkId::new("ours: precompute", relative),
            &relative,
            |b, _| {
                b.iter(|| {
                    d.refactor_with(&f, &lse_deform::resources::Resources::default())
                        .expect("precompute")
                })
            },
        );
    }
    g.finish();
}

fn t4_weight_sweep(c: &mut Criterion) {
    let mesh = main_mesh();
    let cs = scene(&mesh);
    let d = deformer(&mesh, &cs);
    let weights: Vec<f64> = (0..=16).map(|k| 10f64.powi(k)).collect();
    let spd = FaerLlt::supernodal();
    let mut g = c.benchmark_group("t4_weight_sweep");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    g.bench_function("sweep: 17 weights, one analysis", |b| {
        b.iter(|| {
            let sweep = PenaltySweep::new(d.problem(), &spd).expect("sweep");
            black_box(sweep.run(d.problem(), &weights))
        })
    });
    // One penalty matrix: its analysis and its numeric factorisation (the
    // bound is 17 × numeric + analysis).
    let sweep = PenaltySweep::new(d.problem(), &spd).expect("sweep");
    let lower = sweep.normal_matrix(1e8).expect("normal");
    let sym = spd.analyze(lower.symbolic()).expect("analyse");
    g.bench_function("one analysis", |b| {
        b.iter(|| spd.analyze(lower.symbolic()).expect("analyse"))
    });
    g.bench_function("one numeric factorisation", |b| {
        b.iter(|| sym.factorize(lower.as_ref()).expect("factorise"))
    });
    g.finish();
}

fn t5_large(c: &mut Criterion) {
    let mesh = large_mesh();
    let cs = scene(&mesh);
    let mut d = deformer(&mesh, &cs);
    let mut g = c.benchmark_group("t5_large");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    let f = ours();
    g.bench_function("ours: precompute", |b| {
        b.iter(|| {
            d.refactor_with(&f, &lse_deform::resources::Resources::default())
                .expect("precompute")
        })
    });
    d.refactor_with(&f, &lse_deform::resources::Resources::default())
        .expect("precompute");
    let bytes = d.report().nnz.factor_bytes.unwrap_or(0);
    g.bench_function("ours: solve", |b| {
        b.iter(|| d.solve_matrix().expect("solve"))
    });
    if let Some(backend) = reference() {
        let normal = reduced_normal(&d);
        let sym = backend.analyze(normal.symbolic()).expect("analyse");
        g.bench_function("cholmod: factorise", |b| {
            b.iter(|| sym.factorize(normal.as_ref()).expect("factorise"))
        });
    }
    floor_bench(&mut g, bytes);
    g.finish();
}

fn t6_setup(c: &mut Criterion) {
    let mesh = large_mesh();
    let dir = tempfile::tempdir().expect("temp dir");
    let path = match mesh_dir() {
        Some(d) if d.join("igea-537k-subdiv.obj.gz").exists() => d.join("igea-537k-subdiv.obj.gz"),
        _ => {
            let p = dir.path().join("large.obj");
            write_mesh(&mesh, &p).expect("write");
            p
        }
    };
    let cs = scene(&mesh);
    drop(mesh);
    let mut g = c.benchmark_group("t6_setup");
    g.sample_size(10).measurement_time(Duration::from_secs(15));
    g.bench_function("read mesh + build L and A", |b| {
        b.iter(|| {
            let m = read_mesh(&path, lse_deform::limits::MemoryBudget::default())
                .expect("read")
                .mesh;
            Deformer::new(
                m,
                LaplacianKind::Cotangent,
                cs.clone(),
                &lse_deform::SolveOptions::default(),
            )
            .expect("set-up")
        })
    });
    g.finish();
}

fn t7_scaling(c: &mut Criterion) {
    let mut g = c.benchmark_group("t7_scaling");
    g.sample_size(10).measurement_time(Duration::from_secs(4));
    let f = ours();
    for n in [1_000usize, 4_000, 16_000, 64_000] {
        let mesh = generate::with_about_vertices(generate::GeneratedKind::BumpySphere, n, 1)
            .expect("generated mesh");
        let cs = scene(&mesh);
        let mut d = deformer(&mesh, &cs);
        let v = mesh.n_vertices();
        g.bench_with_input(BenchmarkId::new("precompute", v), &v, |b, _| {
            b.iter(|| {
                d.refactor_with(&f, &lse_deform::resources::Resources::default())
                    .expect("precompute")
            })
        });
        d.refactor_with(&f, &lse_deform::resources::Resources::default())
            .expect("precompute");
        g.bench_with_input(BenchmarkId::new("solve", v), &v, |b, _| {
            b.iter(|| d.solve_matrix().expect("solve"))
        });
    }
    g.finish();
}

fn refine(c: &mut Criterion) {
    let mut g = c.benchmark_group("refine");
    g.sample_size(30);
    for (name, file, vertices) in [
        ("bunny", "bunny-35k-stanford.obj", 35_000),
        ("dragon", "dragon-50k.obj", 50_000),
    ] {
        let mesh = named_mesh(file, vertices);
        let d = deformer(&mesh, &scene(&mesh));
        let mut solver = LseSolver::with_formulation(
            d.problem().clone(),
            &ours(),
            &lse_deform::resources::Resources::default(),
        )
        .expect("precompute");
        let mut x0 = Mat::<f64>::zeros(d.problem().n(), 3);
        solver.solve_unrefined_into(x0.as_mut()).expect("solve");
        let mut x = x0.clone();
        solver.refine_solution(&mut x).expect("refine");
        g.bench_function(BenchmarkId::new("solve phase (unrefined)", name), |b| {
            b.iter(|| solver.solve_unrefined_into(x.as_mut()).expect("solve"))
        });
        g.bench_function(BenchmarkId::new("refine auto, later solve", name), |b| {
            b.iter(|| {
                x.copy_from(&x0);
                black_box(solver.refine_solution(&mut x).expect("refine").steps)
            })
        });
        g.bench_function(
            BenchmarkId::new("refine auto, first of the factor", name),
            |b| {
                b.iter(|| {
                    solver.forget_factor_rounding();
                    x.copy_from(&x0);
                    black_box(solver.refine_solution(&mut x).expect("refine").steps)
                })
            },
        );
    }
    g.finish();
}

fn t8_crowded(c: &mut Criterion) {
    let mesh = generate::with_about_vertices(generate::GeneratedKind::BumpySphere, 10_000, 1)
        .expect("generated mesh");
    let mut g = c.benchmark_group("t8_crowded");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    let f = ours();
    for (name, partners) in [("repeated position", 0usize), ("hub relatives", 1000)] {
        for count in [20_000usize, 200_000] {
            let cs = CrowdedScene {
                base: FixedAndHandle::paper_default(&mesh),
                partners,
                count,
                conflict_every: 7,
            }
            .constraints(&mesh)
            .expect("scene");
            g.bench_with_input(BenchmarkId::new(name, count), &count, |b, _| {
                b.iter(|| {
                    let mut d = deformer(&mesh, &cs);
                    d.refactor_with(&f, &lse_deform::resources::Resources::default())
                        .expect("precompute");
                    black_box(d.solve().expect("solve"))
                })
            });
        }
    }
    g.finish();
}

criterion_group!(
    benches,
    t1_precompute,
    t2_solve,
    t3_relative,
    t4_weight_sweep,
    t5_large,
    t6_setup,
    t7_scaling,
    refine,
    t8_crowded
);
criterion_main!(benches);
