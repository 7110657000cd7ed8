//! Every back end checks its factor against the memory budget before it
//! allocates the factor: a refusal comes from the prediction, not after
//! the allocation it should have prevented.

use std::path::Path;
use std::process::{Command, Output};

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `lse-deform ARGS`, without `LSE_MEMORY_LIMIT`, under an address-space
/// limit of `bytes` (`ulimit -v`, `RLIMIT_AS`) when one is given.
fn run(address_limit: Option<u64>, args: &[&str]) -> Output {
    let ulimit = address_limit.map_or(String::new(), |b| format!("ulimit -v {} && ", b / 1024));
    Command::new("sh")
        .arg("-c")
        .arg(format!("{ulimit}exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_lse-deform"))
        .args(args)
        .env_remove("LSE_MEMORY_LIMIT")
        .output()
        .expect("the binary runs")
}

/// An icosphere of 40,962 vertices and its default scene. In its natural
/// order (every subdivision's new vertices after the old ones) the
/// reduced normal matrix's factor has 350,635,563 entries: nalgebra's
/// patterns of `L` and `Lᵀ` alone are 5.6 GB.
fn icosphere_and_scene(dir: &Path) -> (String, String) {
    let mesh = p(dir, "icosphere.obj");
    let o = run(
        None,
        &["generate", "icosphere", "--vertices", "40962", "-o", &mesh],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = p(dir, "scene.json");
    let o = run(None, &["scene", &mesh, "-o", &scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    (mesh, scene)
}

/// nalgebra with the natural ordering, found in the latest round of
/// faults: `CscSymbolicCholesky::factor` built the whole pattern of `L`
/// before the budget was checked, so a fill-heavy ordering held many
/// times the budget (or was killed by the kernel) before the refusal.
/// Now the factor's size is predicted from the elimination tree first.
/// Under 1 GB of address space, where the old code could not even build
/// that pattern (its allocation failed and the process aborted), the run
/// is refused with exit code 2, and the message gives the predicted
/// `nnz(L)` and the budget.
#[test]
fn nalgebra_refuses_a_fill_heavy_ordering_before_building_the_pattern_of_l() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = icosphere_and_scene(dir.path());
    let out = p(dir.path(), "out.obj");
    let args = [
        "deform",
        &mesh,
        "-c",
        &scene,
        "-o",
        &out,
        "--factor",
        "nalgebra",
        "--ordering",
        "natural",
        "--memory-limit",
        "64M",
    ];
    let o = run(Some(1 << 30), &args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for words in [
        "system too large",
        "350635563 entries of L after fill-in, predicted from the elimination tree",
        "more than the memory budget of 64.0 MiB (the memory budget of the solve options)",
    ] {
        assert!(err.contains(words), "expected '{words}' in: {err}");
    }
    assert!(!Path::new(&out).exists());
}

/// faer's `LLᵀ` with a given ordering, found in the same round: faer's
/// symbolic analysis builds the factor's structure, and with the natural
/// ordering it held 1.5 GB (the icosphere of 164k vertices) before the
/// check after it refused a budget of 320 MiB. Now `nnz(L)` is predicted
/// from the elimination tree before that analysis, and the refusal says
/// so.
#[test]
fn faer_refuses_a_fill_heavy_ordering_before_its_analysis() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = icosphere_and_scene(dir.path());
    let out = p(dir.path(), "out.obj");
    for factor in ["faer-supernodal", "faer-simplicial", "faer-auto"] {
        let args = [
            "deform",
            &mesh,
            "-c",
            &scene,
            "-o",
            &out,
            "--factor",
            factor,
            "--ordering",
            "natural",
            "--memory-limit",
            "64M",
        ];
        let o = run(Some(1 << 30), &args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{factor}: {err}");
        for words in [
            "350635563 entries after fill-in, predicted from the elimination tree of the natural ordering",
            "more than the memory budget of 64.0 MiB",
        ] {
            assert!(
                err.contains(words),
                "{factor}: expected '{words}' in: {err}"
            );
        }
    }
}

/// The KKT method's `LDLᵀ` by faer, in the natural ordering: faer's
/// symbolic analysis held 2.7 GB on the icosphere of 164k vertices before
/// the check after it refused 320 MiB. Now the factor is predicted from
/// the elimination tree of the order first.
#[test]
fn kkt_refuses_a_fill_heavy_ordering_before_its_analysis() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = icosphere_and_scene(dir.path());
    let out = p(dir.path(), "out.obj");
    for factor in ["faer-supernodal", "faer-simplicial"] {
        let args = [
            "deform",
            &mesh,
            "-c",
            &scene,
            "-o",
            &out,
            "--method",
            "kkt",
            "--factor",
            factor,
            "--ordering",
            "natural",
            "--memory-limit",
            "64M",
        ];
        let o = run(Some(1 << 30), &args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{factor}: {err}");
        for words in [
            "the LDLᵀ factor of the KKT matrix",
            "predicted from the elimination tree",
            "more than the memory budget of 64.0 MiB",
        ] {
            assert!(
                err.contains(words),
                "{factor}: expected '{words}' in: {err}"
            );
        }
    }
}
