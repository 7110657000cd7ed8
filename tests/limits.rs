//! Resource limits: inputs and systems beyond the memory budget are refused
//! up front with the estimate (`src/limits.rs`), never by the kernel killing
//! the process. The budget is set per run with `LSE_MEMORY_LIMIT`, and per
//! solve with `--memory-limit`.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output};

use lse_deform::error::MeshError;
use lse_deform::mesh::{MeshFormat, read_mesh_bytes};

fn run(limit: Option<&str>, args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lse-deform"));
    cmd.args(args);
    match limit {
        Some(l) => cmd.env("LSE_MEMORY_LIMIT", l),
        None => cmd.env_remove("LSE_MEMORY_LIMIT"),
    };
    cmd.output().expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

/// Exit code 2 (bad input), one line, the expected words, no panic.
fn assert_refused(o: &Output, words: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for w in words {
        assert!(err.contains(w), "expected '{w}' in: {err}");
    }
}

fn generate(dir: &Path, kind: &str, vertices: &str) -> String {
    let mesh = p(dir, &format!("{kind}-{vertices}.obj"));
    let o = run(
        None,
        &["generate", kind, "--vertices", vertices, "-o", &mesh],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    mesh
}

/// A generated mesh and its default scene (`lse-deform scene`).
fn mesh_and_scene(dir: &Path, kind: &str, vertices: &str) -> (String, String) {
    let mesh = generate(dir, kind, vertices);
    let scene = p(dir, "scene.json");
    let o = run(None, &["scene", &mesh, "-o", &scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    (mesh, scene)
}

#[test]
fn a_mesh_file_beyond_the_budget_is_refused_with_its_size() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = generate(dir.path(), "grid", "10000");
    let size = std::fs::metadata(&mesh).unwrap().len();
    assert!(
        size > 256 << 10,
        "the test needs a file over 256 KiB: {size}"
    );
    let o = run(Some("1M"), &["info", &mesh]);
    assert_refused(
        &o,
        &[
            "mesh file too large",
            "memory budget of 1.0 MiB",
            "LSE_MEMORY_LIMIT",
        ],
    );
    // The same file within a larger budget loads.
    let o = run(Some("1G"), &["info", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_header_declaring_more_than_memory_is_refused_before_reserving() {
    // gzip hides the file size, so only the header's counts can tell:
    // 10¹² vertices need 32 TB, more than any machine this runs on.
    let text = b"OFF\n1000000000000 1 0\n0 0 0\n";
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(text).unwrap();
    let bytes = gz.finish().unwrap();
    match read_mesh_bytes(&bytes, MeshFormat::Off) {
        Err(e @ MeshError::TooLarge { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains("1000000000000 vertices"), "{msg}");
            assert!(msg.contains("TiB"), "{msg}");
        }
        other => panic!("expected TooLarge, got {other:?}"),
    }
}

#[test]
fn a_constraints_file_beyond_the_budget_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = generate(dir.path(), "grid", "100");
    let scene = p(dir.path(), "big.json");
    // A valid file made large by its comment: 200 kB × 8 > 1 MiB.
    let comment = "x".repeat(200_000);
    std::fs::write(
        &scene,
        format!(
            r#"{{"constraints": [{{"type": "position", "vertex": 0, "target": [0, 0, 0], "comment": "{comment}"}}]}}"#
        ),
    )
    .unwrap();
    let out = p(dir.path(), "out.obj");
    let o = run(Some("1M"), &["deform", &mesh, "-c", &scene, "-o", &out]);
    assert_refused(&o, &["constraints file too large", "big.json"]);
    assert!(!Path::new(&out).exists());
}

#[test]
fn a_dense_householder_block_beyond_the_budget_is_refused_and_sparse_givens_is_suggested() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = generate(dir.path(), "grid", "10000");
    let scene = p(dir.path(), "scene.json");
    // 2000 relative constraints on one patch: one block of ~2000 unknowns,
    // stored densely: 8 (k m + k m + m²) ≈ 96 MB.
    let o = run(None, &["scene", &mesh, "--relative", "2000", "-o", &scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = p(dir.path(), "out.obj");
    let deform = |qr: &str| {
        run(
            Some("40M"),
            &["deform", &mesh, "-c", &scene, "-o", &out, "--qr", qr],
        )
    };
    assert_refused(
        &deform("dense-householder"),
        &[
            "system too large",
            "dense Householder blocks",
            "sparse-givens QR back end",
        ],
    );
    // The sparse QR of the same constraints fits the same budget.
    let o = deform("sparse-givens");
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_factor_beyond_the_budget_is_refused_after_the_analysis() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = mesh_and_scene(dir.path(), "bumpy-sphere", "20000");
    let out = p(dir.path(), "out.obj");
    for method in [
        &["--method", "nullspace-qr"][..],
        &["--method", "penalty", "--weight", "1e8"],
        &["--method", "kkt"],
        &["--method", "eliminate"],
    ] {
        let mut args = vec!["deform", &mesh, "-c", &scene, "-o", &out];
        args.extend_from_slice(method);
        let o = run(Some("8M"), &args);
        assert_refused(
            &o,
            &[
                "system too large",
                "Cholesky factor",
                "entries after fill-in",
            ],
        );
    }
    let o = run(Some("1G"), &["deform", &mesh, "-c", &scene, "-o", &out]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn the_memory_limit_flag_sets_the_solve_budget_over_the_environment() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = mesh_and_scene(dir.path(), "bumpy-sphere", "20000");
    let out = p(dir.path(), "out.obj");
    let args = ["deform", &mesh, "-c", &scene, "-o", &out, "--memory-limit"];
    let with = |limit: &'static str| [&args[..], &[limit]].concat();
    let o = run(None, &with("8M"));
    assert_refused(
        &o,
        &[
            "Cholesky factor",
            "budget of 8.0 MiB (the memory budget of the solve options)",
        ],
    );
    // The environment's 8M refuses the factor (above); the flag's budget
    // replaces it for the solve.
    let o = run(Some("8M"), &with("1G"));
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(None, &with("12X"));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("'12X' is not a size"), "{}", stderr(&o));
}

/// `compare --memory-limit` bounds every configuration's precompute: the
/// reference's factor beyond 1 KiB is refused with the budget's source,
/// and the same comparison without the flag runs.
#[test]
fn compare_takes_the_memory_limit_flag() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = mesh_and_scene(dir.path(), "grid", "900");
    let args = [
        "compare",
        &mesh,
        "-c",
        &scene,
        "--no-condition",
        "--repeat",
        "1",
    ];
    let o = run(None, &[&args[..], &["--memory-limit", "1K"]].concat());
    assert_refused(
        &o,
        &[
            "Cholesky factor",
            "budget of 1.0 KiB (the memory budget of the solve options)",
        ],
    );
    let o = run(None, &args);
    assert!(o.status.success(), "{}", stderr(&o));
}
