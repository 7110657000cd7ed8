//! Helpers shared by the integration tests that run the `lse-deform`
//! binary: run it, read its standard error, name a file in a temporary
//! directory, start its editor on a free port. (Each test crate that
//! declares `mod common;` uses only some of them.)
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};

/// Whether `CI` is set (to anything but empty, 0, false or no): there a
/// test that cannot run fails instead of passing without checking anything.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| !matches!(v.trim(), "" | "0" | "false" | "no"))
}

/// Outside CI, says on standard error that `what` was skipped and why;
/// under CI (`in_ci`), fails the test instead: CI fails on a skipped test.
pub fn skip_outside_ci(what: &str, why: &str) {
    assert!(!in_ci(), "CI is set and {what} cannot run: {why}");
    eprintln!("skipped {what}: {why}");
}

/// Runs `lse-deform ARGS` to completion.
pub fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lse-deform"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// The standard error of `o`, lossily decoded.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `dir/name` as a string argument.
pub fn path_in(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

/// `lse-deform generate grid --vertices N` and its default `scene` in
/// `dir`: the mesh's and the constraints file's paths.
pub fn grid_and_default_scene(dir: &Path, vertices: usize) -> (String, String) {
    let mesh = path_in(dir, "grid.obj");
    let o = run(&[
        "generate",
        "grid",
        "--vertices",
        &vertices.to_string(),
        "-o",
        &mesh,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = path_in(dir, "scene.json");
    let o = run(&["scene", &mesh, "-o", &scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    (mesh, scene)
}

/// A running `lse-deform edit`: the process, its address and session
/// token.
pub struct Editor {
    pub child: Child,
    pub addr: String,
    pub token: String,
}

/// Starts `lse-deform edit MESH --constraints C --port 0 ARGS` with `env`
/// added to an environment without `LSE_DEFORM_EDIT_TOKEN` and
/// `LSE_MEMORY_LIMIT`, standard error going to `errors`, and parses its
/// first line, `listening on http://ADDR/?token=T`.
pub fn spawn_editor(
    mesh: &Path,
    constraints: &Path,
    args: &[&str],
    env: &[(&str, &str)],
    errors: Stdio,
) -> Editor {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lse-deform"))
        .arg("edit")
        .arg(mesh)
        .arg("--constraints")
        .arg(constraints)
        .args(["--port", "0"])
        .args(args)
        .env_remove("LSE_DEFORM_EDIT_TOKEN")
        .env_remove("LSE_MEMORY_LIMIT")
        .envs(env.iter().copied())
        .stdout(Stdio::piped())
        .stderr(errors)
        .spawn()
        .expect("the editor starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("piped stdout"))
        .read_line(&mut line)
        .expect("its first line");
    let (addr, token) = line
        .trim()
        .strip_prefix("listening on http://")
        .and_then(|s| s.split_once('/'))
        .unwrap_or_else(|| panic!("first line: {line:?}"));
    let token = token.strip_prefix("?token=").unwrap_or("").to_string();
    assert!(addr.starts_with("127.0.0.1:"), "{addr}");
    Editor {
        child,
        addr: addr.to_string(),
        token,
    }
}
