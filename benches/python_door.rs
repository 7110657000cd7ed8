//! Precompute + solve of one mesh scene through Rust, timed the way
//! `tests/python/bench_python_door.py` times the same calls through the
//! Python module (which runs this program and itself in turn, so the two
//! are measured side by side on the same machine state):
//!
//! ```sh
//! cargo bench --bench python_door -- MESH CONSTRAINTS.json REPEATS
//! ```
//!
//! Prints one JSON object: the wall-clock seconds of every
//! `precompute(nullspace-qr) + solve()` (cotangent Laplacian, defaults as
//! the CLI's). Without arguments it prints its usage and exits (so that
//! `cargo bench` alone passes over it).

use std::time::Instant;

use lse_deform::constraints::read_constraints;
use lse_deform::mesh::read_mesh;
use lse_deform::{Deformer, LaplacianKind, NullSpaceQr};

fn main() -> Result<(), lse_deform::Error> {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let [mesh, constraints, repeats] = args.as_slice() else {
        eprintln!("usage: cargo bench --bench python_door -- MESH CONSTRAINTS.json REPEATS");
        return Ok(());
    };
    let repeats: usize = repeats.parse().unwrap_or(1);
    let mesh = read_mesh(mesh.as_ref())?.mesh;
    let set = read_constraints(constraints.as_ref(), mesh.n_vertices())?;
    let mut deformer = Deformer::new(mesh, LaplacianKind::Cotangent, set)?;
    let mut seconds = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let t = Instant::now();
        deformer.precompute(&NullSpaceQr::default())?;
        let solution = deformer.solve()?;
        seconds.push(t.elapsed().as_secs_f64());
        std::hint::black_box(solution);
    }
    println!("{{\"seconds\": {seconds:?}}}");
    Ok(())
}
