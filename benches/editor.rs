//! The editor's per-frame path against the full solve, side by side in one
//! run: on the paper's scene (20 % fixed, a 2 % handle, grouped "fixed" and
//! "handle"), per frame
//!
//! - `basis`: `X = X₀ + R Mᵀ` ([`HandleBasis::evaluate`]);
//! - `basis-f32`: the same written as `f32` ([`HandleBasis::evaluate_f32`],
//!   what a renderer uploads);
//! - `memory-floor`: reading as many bytes as the basis holds (a parallel
//!   sum with eight accumulators over a buffer of [`HandleBasis::bytes`],
//!   in the chunks `basis` reads): the bandwidth bound of `basis` (from
//!   the cache when the basis fits in it, as the Bunny's does and about
//!   all of igea's 30 MB on a 32 MiB last-level cache);
//! - `read-256MiB`: the same read of 256 MiB, from DRAM: scaled by the
//!   basis's bytes, the floor of a basis read from memory;
//! - `full-solve`: `transform_group` and a refined solve with the factor;
//!
//! and, once per selection, `new-selection` (set-up, precompute, response
//! basis) against `deform-precompute` (set-up and precompute: what `deform`
//! does before its solve) — on the Bunny only (igea's precompute is
//! minutes of a criterion run) — then both again alternated round by
//! round, with the median ratio printed (`editor-selection alternated`).
//!
//! Meshes: `LSE_MESH_DIR/bunny-35k-stanford.obj` and
//! `igea-537k-subdiv.obj.gz`, else generated bumpy spheres of 35k and 250k
//! vertices. Run: `LSE_MESH_DIR=../shared/meshes cargo bench --bench editor`.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use faer::Mat;
use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::deform::Affine;
use lse_deform::handle::HandleBasis;
use lse_deform::mesh::{Mesh, generate, read_mesh};
use lse_deform::scene::FixedAndHandle;
use lse_deform::{Deformer, LaplacianKind, formulation::NullSpaceQr};
use rayon::prelude::*;

fn mesh(file: &str, generated: usize) -> (String, Mesh) {
    if let Some(dir) = std::env::var_os("LSE_MESH_DIR").map(PathBuf::from)
        && let Ok(m) = read_mesh(&dir.join(file), lse_deform::limits::MemoryBudget::default())
    {
        return (file.to_string(), m.mesh);
    }
    let m = generate::with_about_vertices(generate::GeneratedKind::BumpySphere, generated, 1)
        .expect("generated mesh");
    (format!("bumpy-sphere-{}k", generated / 1000), m)
}

/// The paper's scene with its regions as groups "fixed" and "handle" at
/// rest (a drag moves the handle by a transform).
fn grouped_scene(mesh: &Mesh) -> ConstraintSet {
    let (fixed, handle) = FixedAndHandle::paper_default(mesh)
        .regions(mesh)
        .expect("scene");
    let p = mesh.positions();
    let mut list = Vec::new();
    for (vs, group) in [(fixed, "fixed"), (handle, "handle")] {
        for v in vs {
            let mut c = Constraint::hard(ConstraintKind::Position {
                vertex: v,
                target: p[v],
            });
            c.group = Some(group.into());
            list.push(c);
        }
    }
    ConstraintSet::from_vec(list).expect("constraints")
}

/// Frame `k` of a circular drag of radius `d` (0.15 of the diagonal,
/// computed once: a bounding box per frame would be a pass over the mesh
/// inside the timed loop).
fn frame(d: f64, k: usize) -> Affine {
    let a = 0.05 * k as f64;
    [
        [1.0, 0.0, 0.0, d * a.sin()],
        [0.0, 1.0, 0.0, d * (1.0 - a.cos())],
        [0.0, 0.0, 1.0, 0.0],
    ]
}

fn per_frame(c: &mut Criterion, file: &str, generated: usize) {
    let (name, mesh) = mesh(file, generated);
    let n = mesh.n_vertices();
    let mut deformer = Deformer::with_formulation(
        mesh.clone(),
        LaplacianKind::Cotangent,
        grouped_scene(&mesh),
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .expect("precompute");
    let basis = HandleBasis::new(&mut deformer, &["handle"]).expect("basis");
    let radius = 0.15 * mesh.bbox_diagonal();
    let mut out = vec![[0.0; 3]; n];
    let floor_buffer = vec![1.0f64; basis.bytes() / 8];
    let mut g = c.benchmark_group(format!("editor-frame/{name}"));
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    let mut k = 0;
    g.bench_function("basis", |b| {
        b.iter(|| {
            k += 1;
            basis
                .evaluate(&[frame(radius, k)], &mut out)
                .expect("evaluate");
            black_box(&out);
        })
    });
    let mut out_f32 = vec![[0.0f32; 3]; n];
    g.bench_function("basis-f32", |b| {
        b.iter(|| {
            k += 1;
            basis
                .evaluate_f32(&[frame(radius, k)], &mut out_f32)
                .expect("evaluate");
            black_box(&out_f32);
        })
    });
    g.bench_function("memory-floor", |b| {
        b.iter(|| black_box(read_all(&floor_buffer)))
    });
    // The same read from DRAM: a buffer far beyond the last-level cache
    // (tens of MiB on current CPUs), whose time scaled by
    // `basis.bytes() / UNCACHED_BYTES` is the floor of a basis that does
    // not stay in the cache between frames.
    let uncached = vec![1.0f64; UNCACHED_BYTES / 8];
    g.bench_function("read-256MiB", |b| b.iter(|| black_box(read_all(&uncached))));
    drop(uncached);
    let mut x = Mat::<f64>::zeros(n, 3);
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    g.bench_function("full-solve", |b| {
        b.iter(|| {
            k += 1;
            deformer
                .transform_group("handle", &frame(radius, k))
                .expect("transform");
            deformer.solver_mut().solve_into(x.as_mut()).expect("solve");
            black_box(&x);
        })
    });
    g.finish();
}

/// The buffer of `read-256MiB`.
const UNCACHED_BYTES: usize = 256 << 20;

/// A parallel sum over `buffer` in the chunks `basis` reads, with eight
/// independent accumulators per task: one dependent add chain would be
/// bound by the add latency (about three times slower here), not by the
/// memory.
fn read_all(buffer: &[f64]) -> f64 {
    buffer
        .par_chunks(8192 * 7)
        .map(|c| {
            let mut acc = [0.0f64; 8];
            for w in c.chunks_exact(8) {
                for (a, v) in acc.iter_mut().zip(w) {
                    *a += v;
                }
            }
            acc.iter().sum::<f64>()
        })
        .sum()
}

fn new_selection(c: &mut Criterion) {
    let (name, mesh) = mesh("bunny-35k-stanford.obj", 35_000);
    let scene = grouped_scene(&mesh);
    let mut g = c.benchmark_group(format!("editor-selection/{name}"));
    g.sample_size(10).measurement_time(Duration::from_secs(15));
    g.bench_function("deform-precompute", |b| {
        b.iter(|| {
            let d = Deformer::with_formulation(
                mesh.clone(),
                LaplacianKind::Cotangent,
                scene.clone(),
                &NullSpaceQr::default(),
                &lse_deform::resources::Resources::default(),
            )
            .expect("precompute");
            black_box(d.report().rank)
        })
    });
    g.bench_function("new-selection", |b| {
        b.iter(|| {
            let mut d = Deformer::with_formulation(
                mesh.clone(),
                LaplacianKind::Cotangent,
                scene.clone(),
                &NullSpaceQr::default(),
                &lse_deform::resources::Resources::default(),
            )
            .expect("precompute");
            black_box(
                HandleBasis::new(&mut d, &["handle"])
                    .expect("basis")
                    .bytes(),
            )
        })
    });
    g.finish();
    alternated_selection(&mesh, &scene, SELECTION_ROUNDS);
}

/// Rounds of [`alternated_selection`].
const SELECTION_ROUNDS: usize = 21;

/// `deform-precompute` and `new-selection` again, one after the other in
/// each of `rounds` rounds, so that a machine whose speed drifts (this one
/// is shared and noisy) slows both alike: prints both medians and the
/// median of the per-round ratios.
fn alternated_selection(mesh: &Mesh, scene: &ConstraintSet, rounds: usize) {
    let timed = |basis: bool| {
        let t = std::time::Instant::now();
        let mut d = Deformer::new(
            mesh.clone(),
            LaplacianKind::Cotangent,
            scene.clone(),
            &lse_deform::SolveOptions::default(),
        )
        .expect("deformer");
        d.refactor_with(
            &NullSpaceQr::default(),
            &lse_deform::resources::Resources::default(),
        )
        .expect("precompute");
        if basis {
            black_box(
                HandleBasis::new(&mut d, &["handle"])
                    .expect("basis")
                    .bytes(),
            );
        }
        t.elapsed().as_secs_f64()
    };
    let (mut precompute, mut selection, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..rounds {
        let (p, s) = (timed(false), timed(true));
        precompute.push(p);
        selection.push(s);
        ratio.push(s / p);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "editor-selection alternated ({rounds} rounds): deform-precompute median {:.1} ms, \
         new-selection median {:.1} ms, median ratio {:.3}",
        median(&mut precompute) * 1e3,
        median(&mut selection) * 1e3,
        median(&mut ratio)
    );
}

fn bunny(c: &mut Criterion) {
    per_frame(c, "bunny-35k-stanford.obj", 35_000);
}

fn igea(c: &mut Criterion) {
    per_frame(c, "igea-537k-subdiv.obj.gz", 250_000);
}

criterion_group!(benches, bunny, new_selection, igea);
criterion_main!(benches);
