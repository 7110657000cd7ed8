//! The editor's HTTP API, through the `lse-deform edit` binary and raw
//! HTTP/1.1 over TCP (so hostile paths reach the server unnormalised):
//! the positions after a transform equal the library's full solve, bad
//! requests get 400/404/405/413 with a message, concurrent clients see
//! whole frames, and the server survives a client that disconnects.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::mesh::{generate, write_mesh};
use lse_deform::{Deformer, LaplacianKind, Mesh, NullSpaceQr};
use serde_json::Value;

const NX: usize = 10;

struct Server {
    child: Child,
    addr: String,
    mesh: Mesh,
    constraints: ConstraintSet,
    _dir: tempfile::TempDir,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A 10 × 10 grid, bottom row "fixed", top row "handle".
fn scene() -> (Mesh, ConstraintSet) {
    let mesh = generate::grid(NX, NX).unwrap();
    let p = mesh.positions().to_vec();
    let mut cs = ConstraintSet::new();
    for v in 0..=NX {
        for (vertex, group) in [(v, "fixed"), (NX * (NX + 1) + v, "handle")] {
            let mut c = Constraint::hard(ConstraintKind::Position {
                vertex,
                target: p[vertex],
            });
            c.group = Some(group.into());
            cs.push(c).unwrap();
        }
    }
    (mesh, cs)
}

fn start(max_body: usize) -> Server {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, cs) = scene();
    let mesh_path = dir.path().join("grid.obj");
    write_mesh(&mesh, &mesh_path).unwrap();
    let c_path = dir.path().join("c.json");
    std::fs::write(&c_path, cs.to_json()).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_lse-deform"))
        .args([
            "edit",
            mesh_path.to_str().unwrap(),
            "--constraints",
            c_path.to_str().unwrap(),
        ])
        .args(["--port", "0", "--max-body-bytes", &max_body.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let addr = line
        .trim()
        .strip_prefix("listening on http://")
        .and_then(|s| s.strip_suffix('/'))
        .unwrap_or_else(|| panic!("first line: {line:?}"))
        .to_string();
    assert!(addr.starts_with("127.0.0.1:"), "{addr}");
    Server {
        child,
        addr,
        mesh,
        constraints: cs,
        _dir: dir,
    }
}

/// One request with `Connection: close`: (status, body).
fn request(addr: &str, method: &str, path: &str, body: &[u8]) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    // The server may answer (413) before reading a large body.
    let _ = s.write_all(body);
    let mut raw = Vec::new();
    let _ = s.read_to_end(&mut raw);
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a response head");
    let head = String::from_utf8_lossy(&raw[..split]).to_lowercase();
    let status: u16 = head[9..12].parse().unwrap();
    let mut payload = raw[split + 4..].to_vec();
    if head.contains("transfer-encoding: chunked") {
        payload = dechunk(&payload);
    }
    (status, payload)
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let line_end = b.windows(2).position(|w| w == b"\r\n").unwrap();
        let size =
            usize::from_str_radix(std::str::from_utf8(&b[..line_end]).unwrap().trim(), 16).unwrap();
        if size == 0 {
            return out;
        }
        out.extend_from_slice(&b[line_end + 2..line_end + 2 + size]);
        b = &b[line_end + 4 + size..];
    }
}

fn json(body: &[u8]) -> Value {
    serde_json::from_slice(body)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(body)))
}

fn positions_f64(addr: &str) -> Vec<[f64; 3]> {
    let (status, body) = request(addr, "GET", "/api/positions?format=f64", b"");
    assert_eq!(status, 200);
    body.chunks_exact(24)
        .map(|c| [0, 1, 2].map(|k| f64::from_le_bytes(c[8 * k..8 * k + 8].try_into().unwrap())))
        .collect()
}

fn transform_body(group: &str, m: [[f64; 4]; 3]) -> Vec<u8> {
    serde_json::to_vec(&serde_json::json!({"group": group, "matrix": m})).unwrap()
}

fn rotation_x(angle: f64, t: [f64; 3]) -> [[f64; 4]; 3] {
    let (c, s) = (angle.cos(), angle.sin());
    [[1.0, 0.0, 0.0, t[0]], [0.0, c, -s, t[1]], [0.0, s, c, t[2]]]
}

/// The server's scene solved by the library (the editor's defaults), with
/// a group moved first if given.
fn library_positions(server: &Server, moved: Option<(&str, [[f64; 4]; 3])>) -> Vec<[f64; 3]> {
    let mut deformer = Deformer::new(
        server.mesh.clone(),
        LaplacianKind::Cotangent,
        server.constraints.clone(),
    )
    .unwrap();
    deformer.precompute(&NullSpaceQr::default()).unwrap();
    if let Some((group, m)) = moved {
        deformer.transform_group(group, &m).unwrap();
    }
    deformer.solve().unwrap().positions
}

#[test]
fn transform_matches_the_library_full_solve() {
    let server = start(1 << 20);
    // Before any move: the positions are the basis at the identity, equal
    // to a full solve, and the report carries the basis's refinement.
    let at_rest = positions_f64(&server.addr);
    let want = library_positions(&server, None);
    let diag = server.mesh.bbox_diagonal();
    for (g, w) in at_rest.iter().zip(&want) {
        for c in 0..3 {
            assert!((g[c] - w[c]).abs() <= 1e-9 * diag, "{g:?} vs {w:?}");
        }
    }
    let report = json(&request(&server.addr, "GET", "/api/report", b"").1);
    assert_eq!(report["refinement"]["mode"], "until 1e-9");
    let estimate = report["forward_error_estimate"].as_f64().unwrap();
    assert!(estimate <= 1e-9, "{estimate:e}");
    assert_eq!(
        report["editor"]["basis"]["forward_error_estimate"],
        estimate
    );
    let m = rotation_x(0.7, [0.1, 0.2, 0.5]);
    let (status, body) = request(
        &server.addr,
        "POST",
        "/api/transform",
        &transform_body("handle", m),
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    assert_eq!(json(&body)["path"], "basis");
    let got = positions_f64(&server.addr);
    let want = library_positions(&server, Some(("handle", m)));
    for (g, w) in got.iter().zip(&want) {
        for c in 0..3 {
            assert!((g[c] - w[c]).abs() <= 1e-9 * diag, "{g:?} vs {w:?}");
        }
    }
    // f32 has the same values, rounded.
    let (status, body) = request(&server.addr, "GET", "/api/positions", b"");
    assert_eq!(status, 200);
    assert_eq!(body.len(), got.len() * 12);
    let x0 = f32::from_le_bytes(body[0..4].try_into().unwrap());
    assert_eq!(x0, got[0][0] as f32);
    // The report states the method and no conflict; the mesh its counts.
    let report = json(&request(&server.addr, "GET", "/api/report", b"").1);
    assert_eq!(report["method"], "nullspace-qr");
    assert_eq!(report["rank"], 2 * (NX + 1));
    assert!(report["max_constraint_residual_relative"].as_f64().unwrap() < 1e-12);
    let mesh = json(&request(&server.addr, "GET", "/api/mesh", b"").1);
    assert_eq!(mesh["vertices"], (NX + 1) * (NX + 1));
    assert_eq!(mesh["faces"], 2 * NX * NX);
}

#[test]
fn the_page_and_its_modules_are_served_and_nothing_else() {
    let server = start(1 << 20);
    let (status, body) = request(&server.addr, "GET", "/", b"");
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&body).contains("<canvas"));
    for module in ["/main.js", "/view.js", "/api.js"] {
        assert_eq!(request(&server.addr, "GET", module, b"").0, 200, "{module}");
    }
    for hostile in [
        "/../Cargo.toml",
        "/..%2fCargo.toml",
        "/%2e%2e/%2e%2e/etc/passwd",
        "/api/../../etc/passwd",
        "/etc/passwd",
        "/nope.js",
    ] {
        let (status, body) = request(&server.addr, "GET", hostile, b"");
        assert!(status == 404 || status == 400, "{hostile}: {status}");
        let text = String::from_utf8_lossy(&body);
        assert!(
            !text.contains("[package]") && !text.contains("root:"),
            "{hostile}: {text}"
        );
    }
    assert_eq!(request(&server.addr, "GET", "/api/transform", b"").0, 405);
    assert_eq!(
        request(&server.addr, "DELETE", "/api/constraints", b"").0,
        405
    );
}

#[test]
fn malformed_requests_get_400_with_a_message_and_change_nothing() {
    let server = start(1 << 20);
    let before = positions_f64(&server.addr);
    let cases: Vec<(&str, &str, Vec<u8>, &str)> = vec![
        (
            "POST",
            "/api/transform",
            b"{not json".to_vec(),
            "invalid JSON",
        ),
        (
            "POST",
            "/api/transform",
            br#"{"group": "handle"}"#.to_vec(),
            "matrix",
        ),
        (
            "POST",
            "/api/transform",
            br#"{"group": "handle", "matrix": [[1,0,0],[0,1,0],[0,0,1]]}"#.to_vec(),
            "invalid JSON",
        ),
        (
            "POST",
            "/api/transform",
            transform_body("nope", rotation_x(0.0, [0.0; 3])),
            "nope",
        ),
        (
            "POST",
            "/api/transform",
            br#"{"group": "handle", "matrix": [[1,0,0,1e400],[0,1,0,0],[0,0,1,0]]}"#.to_vec(),
            "invalid JSON",
        ),
        ("PUT", "/api/constraints", b"[1, 2".to_vec(), ""),
        (
            "PUT",
            "/api/constraints",
            br#"{"constraints": [{"type": "position", "vertex": 100000, "target": [0,0,0]}]}"#
                .to_vec(),
            "100000",
        ),
        ("PUT", "/api/constraints", vec![0xff, 0xfe, 0x00], "UTF-8"),
        (
            "PUT",
            "/api/settings",
            br#"{"method": "bogus"}"#.to_vec(),
            "bogus",
        ),
        (
            "PUT",
            "/api/settings",
            br#"{"laplacian": 3}"#.to_vec(),
            "settings",
        ),
        (
            "PUT",
            "/api/settings",
            br#"{"colour": "red"}"#.to_vec(),
            "colour",
        ),
        (
            "POST",
            "/api/iterate",
            br#"{"iterations": -1}"#.to_vec(),
            "invalid JSON",
        ),
        ("GET", "/api/positions?format=xyz", vec![], "xyz"),
    ];
    for (method, path, body, needle) in cases {
        let (status, answer) = request(&server.addr, method, path, &body);
        assert_eq!(
            status,
            400,
            "{method} {path}: {}",
            String::from_utf8_lossy(&answer)
        );
        let message = json(&answer)["error"].as_str().unwrap().to_string();
        assert!(message.contains(needle), "{method} {path}: {message}");
        assert!(!message.contains('\n'), "one line: {message}");
    }
    assert_eq!(positions_f64(&server.addr), before);
    assert_eq!(
        json(&request(&server.addr, "GET", "/api/report", b"").1)["method"],
        "nullspace-qr"
    );
}

#[test]
fn huge_bodies_get_413_stating_the_limit() {
    let server = start(50_000);
    let big = vec![b' '; 200_000];
    let (status, body) = request(&server.addr, "PUT", "/api/constraints", &big);
    assert_eq!(status, 413);
    assert!(
        json(&body)["error"]
            .as_str()
            .unwrap()
            .contains("50000 bytes")
    );
    // Still serving.
    assert_eq!(request(&server.addr, "GET", "/api/mesh", b"").0, 200);
}

#[test]
fn settings_switch_method_and_energy() {
    let server = start(1 << 20);
    let (status, body) = request(
        &server.addr,
        "PUT",
        "/api/settings",
        br#"{"method": "kkt"}"#,
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    assert_eq!(json(&body)["method"], "kkt");
    let (status, body) = request(
        &server.addr,
        "PUT",
        "/api/settings",
        br#"{"energy": "arap", "arap_iterations_per_frame": 3}"#,
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let m = rotation_x(0.5, [0.0, 0.0, 0.3]);
    let (status, body) = request(
        &server.addr,
        "POST",
        "/api/transform",
        &transform_body("handle", m),
    );
    assert_eq!(status, 200);
    assert_eq!(json(&body)["path"], "arap");
    let (status, body) = request(
        &server.addr,
        "POST",
        "/api/iterate",
        br#"{"iterations": 5}"#,
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let report = json(&request(&server.addr, "GET", "/api/report", b"").1);
    assert_eq!(
        report["arap"]["iterations"],
        3 + 3 + 5,
        "{}",
        report["arap"]
    );
    // Hard constraints hold: the fixed row did not move; the handle row is at R p + t.
    let p = positions_f64(&server.addr);
    let rest = server.mesh.positions();
    for v in 0..=NX {
        for c in 0..3 {
            assert!((p[v][c] - rest[v][c]).abs() < 1e-9);
        }
        let h = NX * (NX + 1) + v;
        let q = rest[h];
        let want = [0, 1, 2].map(|r| m[r][0] * q[0] + m[r][1] * q[1] + m[r][2] * q[2] + m[r][3]);
        for c in 0..3 {
            assert!((p[h][c] - want[c]).abs() < 1e-9, "{:?} vs {want:?}", p[h]);
        }
    }
}

#[test]
fn concurrent_clients_see_whole_frames() {
    let server = start(1 << 20);
    let addr = server.addr.clone();
    let threads: Vec<_> = (0..6)
        .map(|k| {
            let addr = addr.clone();
            std::thread::spawn(move || {
                for f in 0..8 {
                    let t = [0.01 * k as f64, 0.02 * f as f64, 0.3];
                    let (status, _) = request(
                        &addr,
                        "POST",
                        "/api/transform",
                        &transform_body("handle", rotation_x(0.0, t)),
                    );
                    assert_eq!(status, 200);
                    let p = positions_f64(&addr);
                    // Every handle vertex moved by one and the same translation.
                    let rest = generate::grid(NX, NX).unwrap().positions().to_vec();
                    let h0 = NX * (NX + 1);
                    let shift = [0, 1, 2].map(|c| p[h0][c] - rest[h0][c]);
                    for v in h0..h0 + NX + 1 {
                        for c in 0..3 {
                            assert!((p[v][c] - rest[v][c] - shift[c]).abs() < 1e-9);
                        }
                    }
                }
            })
        })
        .collect();
    for t in threads {
        t.join().unwrap();
    }
}

#[test]
fn a_client_that_disconnects_mid_request_does_not_stop_the_server() {
    let server = start(1 << 20);
    for _ in 0..3 {
        let mut s = TcpStream::connect(&server.addr).unwrap();
        s.write_all(
            b"PUT /api/constraints HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n{\"constr",
        )
        .unwrap();
        drop(s);
        let mut s = TcpStream::connect(&server.addr).unwrap();
        s.write_all(b"GET /api/posi").unwrap();
        drop(s);
    }
    assert_eq!(request(&server.addr, "GET", "/api/mesh", b"").0, 200);
    let (status, _) = request(
        &server.addr,
        "POST",
        "/api/transform",
        &transform_body("handle", rotation_x(0.1, [0.0; 3])),
    );
    assert_eq!(status, 200);
}

#[test]
fn moving_the_fixed_group_falls_back_to_solves_until_it_is_back_at_rest() {
    let server = start(1 << 20);
    let path = |group: &str, m| {
        json(
            &request(
                &server.addr,
                "POST",
                "/api/transform",
                &transform_body(group, m),
            )
            .1,
        )["path"]
            .clone()
    };
    let id = rotation_x(0.0, [0.0; 3]);
    let lift = rotation_x(0.0, [0.0, 0.0, 0.1]);
    assert_eq!(path("fixed", id), "basis");
    assert_eq!(path("handle", lift), "basis");
    assert_eq!(path("fixed", lift), "full-solve");
    assert_eq!(path("handle", id), "full-solve");
    // Both lifted by the same translation: the whole grid moves rigidly.
    let p = positions_f64(&server.addr);
    let rest = server.mesh.positions();
    assert_eq!(path("handle", lift), "full-solve");
    let p2 = positions_f64(&server.addr);
    for (q, r) in p2.iter().zip(rest) {
        assert!((q[2] - r[2] - 0.1).abs() < 1e-9, "{q:?}");
    }
    assert!(p.len() == p2.len());
    assert_eq!(path("fixed", id), "basis");
}

/// A conflicting constraint reaches the report panel: `PUT
/// /api/constraints` with the first fixed vertex asked elsewhere answers a
/// report whose warnings name it and the constraint it contradicts, and so
/// does `GET /api/report` after a frame, with the linear and the ARAP
/// energy.
#[test]
fn a_conflict_is_among_the_report_warnings() {
    let server = start(1 << 20);
    let (_, mut cs) = scene();
    let n = cs.len();
    cs.push(Constraint::hard(ConstraintKind::Position {
        vertex: 0,
        target: [0.0, 0.0, 0.5],
    }))
    .unwrap();
    let needle = format!("constraint {n} conflicts with constraint 0 and was dropped");
    let has = |report: &Value| {
        report["warnings"].as_array().is_some_and(|w| {
            w.iter()
                .any(|w| w.as_str().is_some_and(|w| w.starts_with(&needle)))
        })
    };
    let (status, body) = request(
        &server.addr,
        "PUT",
        "/api/constraints",
        cs.to_json().as_bytes(),
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    assert!(has(&json(&body)), "{}", String::from_utf8_lossy(&body));
    let m = rotation_x(0.3, [0.0, 0.0, 0.2]);
    let (status, _) = request(
        &server.addr,
        "POST",
        "/api/transform",
        &transform_body("handle", m),
    );
    assert_eq!(status, 200);
    let report = json(&request(&server.addr, "GET", "/api/report", b"").1);
    assert!(has(&report), "{report}");
    let (status, body) = request(
        &server.addr,
        "PUT",
        "/api/settings",
        br#"{"energy": "arap"}"#,
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let (status, _) = request(
        &server.addr,
        "POST",
        "/api/transform",
        &transform_body("handle", m),
    );
    assert_eq!(status, 200);
    let report = json(&request(&server.addr, "GET", "/api/report", b"").1);
    assert!(has(&report), "{report}");
}
