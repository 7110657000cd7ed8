//! Every file the binary writes appears whole or not at all, and `solve`
//! checks its outputs before any work, as `deform` does.
//!
//! A full disk is made real without root or a mount: the binary runs under
//! a file size limit (`ulimit -f`, with `SIGXFSZ` ignored), so its writes
//! past the limit fail with `EFBIG` just as they fail with `ENOSPC` on a
//! full device.

use std::path::Path;
use std::process::{Command, Output};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_lse-deform")
}

fn run(args: &[&str]) -> Output {
    Command::new(bin())
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Runs the binary with writes limited to a few KiB per file.
#[cfg(unix)]
fn run_on_a_full_disk(args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(r#"trap "" XFSZ; ulimit -f 4 && exec "$0" "$@""#)
        .arg(bin())
        .args(args)
        .output()
        .expect("sh runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A 900-vertex grid and its fixed-and-handle scene in `dir`.
fn grid_and_scene(dir: &Path) -> (String, String) {
    let mesh = p(dir, "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "900", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = p(dir, "scene.json");
    let o = run(&["scene", &mesh, "-o", &scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    (mesh, scene)
}

/// `deform -o` on a full disk: the error is reported (exit 2, naming the
/// file) and the previous good mesh is left whole, with no temporary file
/// beside it.
#[cfg(unix)]
#[test]
fn a_full_disk_keeps_the_previous_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let out = p(dir.path(), "out.obj");
    let o = run(&["deform", &mesh, "-c", &scene, "-o", &out]);
    assert!(o.status.success(), "{}", stderr(&o));
    let good = std::fs::read(&out).unwrap();
    assert!(good.len() > 16 << 10, "larger than the limit");
    let o = run_on_a_full_disk(&["deform", &mesh, "-c", &scene, "-o", &out]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("out.obj"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        std::fs::read(&out).unwrap() == good,
        "the old mesh is intact"
    );
    assert_eq!(names(dir.path()), ["grid.obj", "out.obj", "scene.json"]);
}

/// The same for every other writer: `solve`'s `X.mtx`, a `--report`, a
/// generated mesh, a scene and `export-system`'s files.
#[cfg(unix)]
#[test]
fn a_full_disk_keeps_every_previous_output() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let sys = p(dir.path(), "sys");
    let o = run(&["export-system", &mesh, "-c", &scene, "-o", &sys]);
    assert!(o.status.success(), "{}", stderr(&o));
    let x = p(dir.path(), "X.mtx");
    let report = p(dir.path(), "report.json");
    let solve = ["solve", &sys, "-o", &x, "--report", &report];
    let o = run(&solve);
    assert!(o.status.success(), "{}", stderr(&o));
    let big = p(dir.path(), "big.obj");
    let generate = ["generate", "grid", "--vertices", "900", "-o", &big];
    assert!(run(&generate).status.success());
    let contents = |paths: &[&str]| -> Vec<Vec<u8>> {
        paths.iter().map(|f| std::fs::read(f).unwrap()).collect()
    };
    let a_mtx = p(dir.path(), "sys/A.mtx");
    let files = [x.as_str(), &report, &big, &scene, &a_mtx];
    let kept = contents(&files);
    let listing = names(dir.path());
    let sys_listing = names(Path::new(&sys));
    // X.mtx alone is over the limit: 900 × 3 numbers.
    let o = run_on_a_full_disk(&solve);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("X.mtx"), "{}", stderr(&o));
    assert!(run_on_a_full_disk(&generate).status.code() == Some(2));
    let o = run_on_a_full_disk(&["export-system", &mesh, "-c", &scene, "-o", &sys]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("A.mtx"), "{}", stderr(&o));
    let now = contents(&files);
    for (k, f) in files.iter().enumerate() {
        assert!(now[k] == kept[k], "{f} changed");
    }
    assert_eq!(names(dir.path()), listing, "no temporary file left");
    assert_eq!(names(Path::new(&sys)), sys_listing);
}

/// `solve --report missing-dir/r.json` fails before any work: no `X.mtx`
/// is written, and with a missing input too it is the output that is
/// reported (the inputs were not read).
#[test]
fn solve_checks_its_outputs_before_working() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let sys = p(dir.path(), "sys");
    let o = run(&["export-system", &mesh, "-c", &scene, "-o", &sys]);
    assert!(o.status.success(), "{}", stderr(&o));
    let x = p(dir.path(), "X.mtx");
    let report = p(dir.path(), "missing-dir/r.json");
    let o = run(&["solve", &sys, "-o", &x, "--report", &report]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("missing-dir/r.json"), "{err}");
    assert!(
        !Path::new(&x).exists(),
        "X.mtx was written before the check"
    );
    let o = run(&[
        "solve",
        &p(dir.path(), "no-such-system"),
        "-o",
        &p(dir.path(), "missing-dir/X.mtx"),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("missing-dir/X.mtx") && !err.contains("no-such-system"),
        "{err}"
    );
    assert_eq!(names(dir.path()), ["grid.obj", "scene.json", "sys"]);
}

/// Successful writes leave exactly the files asked for.
#[test]
fn writes_leave_no_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let out = p(dir.path(), "out.ply.gz");
    let report = p(dir.path(), "r.json");
    for _ in 0..2 {
        let o = run(&[
            "deform", &mesh, "-c", &scene, "-o", &out, "--report", &report,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let m = lse_deform::mesh::read_mesh(Path::new(&out)).unwrap().mesh;
    assert_eq!(m.n_vertices(), 900);
    assert_eq!(
        names(dir.path()),
        ["grid.obj", "out.ply.gz", "r.json", "scene.json"]
    );
}
