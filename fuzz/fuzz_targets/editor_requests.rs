//! Requests to the editor's HTTP service, through its whole router in
//! process (token and `Host`/`Origin` guard, body limits, handlers): every
//! answer is a status below 500, every refusal carries a JSON body
//! `{"error": text, "kind": word}` (to HEAD: no body, and the JSON content
//! type), and after each request the session still answers
//! `/api/progress` as idle.
//!
//! An input is up to four requests separated by NUL bytes. A request is
//! a head, an empty line, and the body: the head's first line is
//! `METHOD PATH`, the others `name: value` headers. The session's token and
//! a `Host` it accepts are added unless the head names them itself, or
//! names `-authorization` / `-host` to leave them out. Each input starts
//! a fresh session on a 5 × 5 grid with its bottom row `fixed` and top row
//! `handle`, so that a crash reproduces from its input alone.
#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::editor::EditOptions;
use lse_deform::editor::in_process::{ADDRESS, Body, InProcessEditor, http};
use lse_deform::mesh::{Mesh, generate};

const TOKEN: &str = "0123456789abcdef0123456789abcdef";

fn scene() -> &'static (Mesh, ConstraintSet, EditOptions) {
    static SCENE: OnceLock<(Mesh, ConstraintSet, EditOptions)> = OnceLock::new();
    SCENE.get_or_init(|| {
        let n = 4;
        let mesh = generate::grid(n, n).expect("a grid");
        let p = mesh.positions().to_vec();
        let mut cs = ConstraintSet::new();
        for v in 0..=n {
            for (vertex, group) in [(v, "fixed"), (n * (n + 1) + v, "handle")] {
                let mut c = Constraint::hard(ConstraintKind::Position {
                    vertex,
                    target: p[vertex],
                });
                c.group = Some(group.into());
                cs.push(c).expect("a constraint");
            }
        }
        let options = EditOptions {
            mesh: "grid.obj".into(),
            constraints: None,
            host: "127.0.0.1".into(),
            port: 0,
            max_body_bytes: 1 << 16,
            token: None,
            body_timeout: std::time::Duration::from_secs(5),
            idle_timeout: std::time::Duration::from_secs(5),
        };
        (mesh, cs, options)
    })
}

/// The request in `bytes`, or `None` when it is not one (an invalid
/// method, URI or header).
fn request(bytes: &[u8]) -> Option<http::Request<Body>> {
    let split = bytes.windows(2).position(|w| w == b"\n\n");
    let (head, body) = match split {
        Some(i) => (&bytes[..i], &bytes[i + 2..]),
        None => (bytes, &[][..]),
    };
    let head = std::str::from_utf8(head).ok()?;
    let mut lines = head.lines();
    let (method, path) = lines.next()?.split_once(' ')?;
    let mut builder = http::Request::builder().method(method).uri(path);
    let (mut auth, mut host) = (true, true);
    for line in lines {
        match line.trim() {
            "-authorization" => auth = false,
            "-host" => host = false,
            line => {
                let (name, value) = line.split_once(':')?;
                let name = name.trim().to_ascii_lowercase();
                auth &= name != "authorization";
                host &= name != "host";
                builder = builder.header(name, value.trim());
            }
        }
    }
    if auth {
        builder = builder.header("authorization", format!("Bearer {TOKEN}"));
    }
    if host {
        builder = builder.header("host", ADDRESS);
    }
    builder.body(Body::from(body.to_vec())).ok()
}

fuzz_target!(|data: &[u8]| {
    let (mesh, constraints, options) = scene();
    let editor = InProcessEditor::new(
        mesh.clone(),
        Some(constraints.clone()),
        options,
        TOKEN.to_string(),
    )
    .expect("the session starts");
    for part in data.split(|&b| b == 0).filter(|p| !p.is_empty()).take(4) {
        let Some(r) = request(part) else {
            continue;
        };
        let head = r.method() == http::Method::HEAD;
        let answer = editor.answer(r);
        let status = answer.status.as_u16();
        assert!(status < 500, "{status}: {:?}", answer.body);
        if status >= 400 && head {
            // A HEAD answer's body is never sent (RFC 9110 §9.3.2: hyper
            // drops it on the wire, whether or not the router produced
            // one); its headers still say what the body would be.
            let kind = answer.headers.get("content-type").map(|v| v.as_bytes());
            assert_eq!(kind, Some(&b"application/json"[..]), "{status}");
        } else if status >= 400 {
            let v: serde_json::Value =
                serde_json::from_slice(&answer.body).expect("a JSON error body");
            assert!(v["error"].is_string() && v["kind"].is_string(), "{v}");
        }
        let progress = editor.answer(editor.request("GET", "/api/progress", ""));
        assert_eq!(progress.status.as_u16(), 200);
        let p: serde_json::Value = serde_json::from_slice(&progress.body).expect("JSON");
        assert_eq!(p["busy"], false, "{p}");
    }
});
