//! Requests and files designed to make the process allocate out of
//! proportion to their size get a typed refusal before the allocation, and
//! leave a server answering: a response basis of thousands of groups or
//! beyond the memory budget (the editor, 413), Matrix Market headers that
//! declare huge shapes (`solve`), streams that never end (`/dev/zero` as a
//! matrix, a mesh or a constraints file), and 10⁵ distinct groups (indexed,
//! not scanned).
//!
//! The command-line cases run under `ulimit -v` (2 GiB of address space):
//! before the checks, each of them allocated gigabytes and was aborted or
//! ran out of memory there; now each ends with its typed message and exit
//! code 2 within a few megabytes.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::Instant;

use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::mesh::{generate, write_mesh};
use serde_json::Value;

mod common;

// ---------------------------------------------------------------------------
// Groups

/// 3·10⁵ distinct groups: added and each looked up once. Indexed by name
/// this takes well under a second; the former scan of the group list per
/// constraint and per lookup was 4.5·10¹⁰ comparisons each way (10⁵ groups
/// took 22 s in `deform`), minutes here.
#[test]
fn distinct_groups_are_indexed_not_scanned() {
    const N: usize = 300_000;
    let set = ConstraintSet::from_vec(
        (0..N)
            .map(|i| Constraint::position(i, [0.0; 3]).in_group(format!("g{i}")))
            .collect(),
    )
    .unwrap();
    assert_eq!(set.group_names().len(), N);
    for i in (0..N).rev() {
        assert_eq!(set.group(&format!("g{i}")), &[i]);
    }
    assert!(set.group("g").is_empty());
}

// ---------------------------------------------------------------------------
// The editor

/// `lse-deform edit` on a 10 × 10 grid with a "fixed" bottom row and a
/// "handle" top row; killed when dropped.
struct Server {
    child: Child,
    addr: String,
    token: String,
    _dir: tempfile::TempDir,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

const NX: usize = 10;

fn start(env: &[(&str, &str)]) -> Server {
    let dir = tempfile::tempdir().unwrap();
    let mesh = generate::grid(NX, NX).unwrap();
    let mesh_path = dir.path().join("grid.obj");
    write_mesh(&mesh, &mesh_path).unwrap();
    let p = mesh.positions();
    let mut cs = ConstraintSet::new();
    for v in 0..=NX {
        for (vertex, group) in [(v, "fixed"), (NX * (NX + 1) + v, "handle")] {
            cs.push(
                Constraint::hard(ConstraintKind::Position {
                    vertex,
                    target: p[vertex],
                })
                .in_group(group),
            )
            .unwrap();
        }
    }
    let c_path = dir.path().join("c.json");
    std::fs::write(&c_path, cs.to_json()).unwrap();
    let e = common::spawn_editor(&mesh_path, &c_path, &[], env, Stdio::null());
    Server {
        addr: e.addr,
        token: e.token,
        child: e.child,
        _dir: dir,
    }
}

/// One request (`Connection: close`): the status and the body.
fn request(s: &Server, method: &str, path: &str, body: &[u8]) -> (u16, Vec<u8>) {
    let mut stream = TcpStream::connect(&s.addr).unwrap();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {}\r\nAuthorization: Bearer {}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        s.addr,
        s.token,
        body.len()
    );
    stream.write_all(head.as_bytes()).unwrap();
    stream.write_all(body).unwrap();
    let mut answer = Vec::new();
    stream.read_to_end(&mut answer).unwrap();
    let split = answer
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a complete head");
    let head = String::from_utf8_lossy(&answer[..split]).to_string();
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("status line: {head}"));
    let mut body = answer[split + 4..].to_vec();
    if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        body = dechunk(&body);
    }
    (status, body)
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    while let Some(i) = b.windows(2).position(|w| w == b"\r\n") {
        let size = usize::from_str_radix(std::str::from_utf8(&b[..i]).unwrap().trim(), 16).unwrap();
        if size == 0 {
            break;
        }
        out.extend_from_slice(&b[i + 2..i + 2 + size]);
        b = &b[i + 2 + size + 2..];
    }
    out
}

fn json(body: &[u8]) -> Value {
    serde_json::from_slice(body).unwrap_or_else(|e| {
        panic!(
            "not JSON ({e}): {}",
            String::from_utf8_lossy(&body[..body.len().min(300)])
        )
    })
}

/// `fixed` on the bottom row and one constraint per group on the other
/// vertices, cycling: `groups` movable groups.
fn many_groups(groups: usize) -> Vec<u8> {
    let mut cs = ConstraintSet::new();
    for v in 0..=NX {
        cs.push(Constraint::position(v, [v as f64, 0.0, 0.0]).in_group("fixed"))
            .unwrap();
    }
    let others = (NX + 1) * (NX + 1) - (NX + 1);
    for g in 0..groups {
        let v = NX + 1 + g % others;
        cs.push(Constraint::position(v, [0.0, 1.0, 0.0]).in_group(format!("g{g}")))
            .unwrap();
    }
    cs.to_json().into_bytes()
}

/// A refused change: 413 `too-large` with `words` in the message (the time
/// it took is printed, not tested: speed belongs to the experiments), and the editor
/// unchanged and answering: progress idle, the same constraints, a drag of
/// the handle on the basis path.
fn assert_refused_and_unchanged(s: &Server, body: &[u8], words: &[&str]) {
    let (status, before) = request(s, "GET", "/api/constraints", b"");
    assert_eq!(status, 200);
    let t = Instant::now();
    let (status, answer) = request(s, "PUT", "/api/constraints", body);
    let seconds = t.elapsed().as_secs_f64();
    eprintln!("refused in {seconds:.3} s");
    let answer = json(&answer);
    assert_eq!(status, 413, "{answer}");
    assert_eq!(answer["kind"], "too-large", "{answer}");
    let message = answer["error"].as_str().unwrap();
    for w in words {
        assert!(message.contains(w), "expected {w:?} in: {message}");
    }
    let (status, progress) = request(s, "GET", "/api/progress", b"");
    assert_eq!(status, 200);
    assert_eq!(json(&progress)["busy"], false);
    assert_eq!(request(s, "GET", "/api/constraints", b""), (200, before));
    let drag = br#"{"group": "handle", "matrix": [[1, 0, 0, 0.1], [0, 1, 0, 0], [0, 0, 1, 0]]}"#;
    let (status, frame) = request(s, "POST", "/api/transform", drag);
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&frame));
    assert_eq!(json(&frame)["path"], "basis");
}

/// 3,000 groups of one constraint: a response basis of 12,003 columns
/// (about 1 GiB on this grid; on a 2,000-vertex mesh it was 2.6 GB and
/// answered 500 after it). Refused before any work: more groups than the
/// basis takes.
#[test]
fn thousands_of_groups_get_413_at_once_and_change_nothing() {
    let s = start(&[]);
    assert_refused_and_unchanged(&s, &many_groups(3000), &["3000", "groups", "256"]);
}

/// 100 groups (under the count cap) with a memory budget below their
/// basis's estimate: refused with the estimate and the budget.
///
/// Ignored for now: the budget is of the whole process (the factor and
/// the basis are both checked on top of the resident set), so a budget
/// below this grid's 4.6 MB basis no longer lets the editor start at all
/// (tests/editor_api.rs
/// `a_budget_below_what_the_process_holds_refuses_the_start`); a budget
/// between the start and the basis is the editor's resident set plus a
/// few MB, which this test cannot know before the editor runs. The Python
/// door tests that window in its own process
/// (tests/python/test_basis.py).
#[test]
#[ignore = "the window between the start's and the basis's budget depends on the editor's resident set"]
fn a_basis_beyond_the_memory_budget_gets_413_and_changes_nothing() {
    let s = start(&[("LSE_MEMORY_LIMIT", "2M")]);
    assert_refused_and_unchanged(
        &s,
        &many_groups(100),
        &["response basis", "100 group", "memory budget of 2.0 MiB"],
    );
    // Under the budget the same server builds a basis.
    let (status, answer) = request(&s, "PUT", "/api/constraints", &many_groups(3));
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&answer));
}

// ---------------------------------------------------------------------------
// Files

/// `sh -c 'ulimit -v 2 GiB; exec lse-deform ARGS'` in `dir`.
fn run_limited(dir: &Path, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 2097152 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_lse-deform"))
        .args(args)
        .current_dir(dir)
        .env_remove("LSE_MEMORY_LIMIT")
        .output()
        .unwrap()
}

/// Exit code 2 and one `error:` line holding every word.
fn assert_refused(out: &Output, words: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{:?}: {stderr}", out.status);
    let error = stderr
        .lines()
        .find(|l| l.starts_with("error:"))
        .unwrap_or_else(|| panic!("no error line: {stderr}"));
    for w in words {
        assert!(error.contains(w), "expected {w:?} in: {error}");
    }
}

const ONE_ROW: &str = "%%MatrixMarket matrix array real general\n1 3\n0\n0\n0\n";

/// Two 66-byte files declaring 3·10⁸ columns with one entry each: refused
/// from their headers (before: 3.8–11 GB allocated for the column
/// pointers, then the same problem refused as singular).
#[test]
fn matrix_headers_declaring_huge_shapes_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let wide = "%%MatrixMarket matrix coordinate real general\n1 300000000 1\n1 1 1\n";
    std::fs::write(dir.path().join("A.mtx"), wide).unwrap();
    std::fs::write(dir.path().join("B.mtx"), wide).unwrap();
    std::fs::write(dir.path().join("C.mtx"), ONE_ROW).unwrap();
    std::fs::write(dir.path().join("D.mtx"), ONE_ROW).unwrap();
    let out = run_limited(dir.path(), &["solve", ".", "-o", "x.mtx"]);
    assert_refused(&out, &["300000000 unknowns", "no unique solution"]);

    // A one-entry coordinate C of 3·10⁸ rows (2.3 GB as a dense matrix)
    // for a 2-row A: the shapes are compared before C is expanded.
    let square = "%%MatrixMarket matrix coordinate real general\n2 2 2\n1 1 1\n2 2 1\n";
    std::fs::write(dir.path().join("A.mtx"), square).unwrap();
    std::fs::write(
        dir.path().join("B.mtx"),
        "%%MatrixMarket matrix coordinate real general\n1 2 1\n1 1 1\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("C.mtx"),
        "%%MatrixMarket matrix coordinate real general\n300000000 3 1\n1 1 1\n",
    )
    .unwrap();
    let out = run_limited(dir.path(), &["solve", ".", "-o", "x.mtx"]);
    assert_refused(&out, &["C must have as many rows as A", "C 300000000 × 3"]);
}

/// Streams that never end, as a matrix, a mesh (a `.obj`, `.off` or `.ply`
/// name for `/dev/zero`) or a constraints file: each refused from its
/// first bytes (before: read until the allocator gave up).
#[test]
fn endless_streams_are_refused_not_read_to_exhaustion() {
    let zero = Path::new("/dev/zero");
    if !zero.exists() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("B.mtx"),
        "%%MatrixMarket matrix coordinate real general\n1 2 1\n1 1 1\n",
    )
    .unwrap();
    std::fs::write(d.join("C.mtx"), ONE_ROW).unwrap();
    std::fs::write(d.join("D.mtx"), ONE_ROW).unwrap();
    let out = run_limited(
        d,
        &[
            "solve",
            "--a",
            "/dev/zero",
            "--b",
            "B.mtx",
            "--c",
            "C.mtx",
            "--d",
            "D.mtx",
            "-o",
            "x.mtx",
        ],
    );
    assert_refused(&out, &["/dev/zero, line 1", "longer than"]);

    for name in ["zero.obj", "zero.off", "zero.ply"] {
        std::os::unix::fs::symlink(zero, d.join(name)).unwrap();
        let out = run_limited(d, &["info", name]);
        assert_refused(&out, &["parse error", "line 1"]);
    }

    write_mesh(&generate::grid(3, 3).unwrap(), &d.join("grid.obj")).unwrap();
    let out = run_limited(
        d,
        &["deform", "grid.obj", "-c", "/dev/zero", "-o", "out.obj"],
    );
    assert_refused(&out, &["malformed JSON at line 1, column 1"]);
}
