//! The editor's HTTP service in process: the same guard and routes as
//! `lse-deform edit`, answering requests handed to it directly instead of
//! read from a socket. For property tests of request sequences and for the
//! fuzz target, which must reach the handlers through everything a real
//! request passes (the token, `Host`/`Origin` checks, body limits, JSON
//! errors) without the cost of a connection per request.

use std::net::SocketAddr;
use std::sync::OnceLock;

pub use axum::body::{Body, Bytes};
pub use axum::http;
use axum::http::{HeaderMap, Request, StatusCode};
use hyper::service::Service;
use hyper_util::service::TowerToHyperService;

use super::{App, Change, EditOptions, PUBLIC, guard, router};
use crate::constraints::ConstraintSet;
use crate::error::{Error, ProblemError};
use crate::mesh::Mesh;

/// The address an in-process editor takes itself to be bound at: requests
/// must name it (or `localhost:8765`) in `Host`, as a browser would.
pub const ADDRESS: &str = "127.0.0.1:8765";

/// An answer: status, headers and the whole body.
#[derive(Debug, Clone)]
pub struct Answer {
    /// The status.
    pub status: StatusCode,
    /// The headers.
    pub headers: HeaderMap,
    /// The body, collected.
    pub body: Bytes,
}

/// An editor session served in process. `answer` may be called from
/// several threads at once: requests then run concurrently, as on a real
/// server (handlers on the calling threads, builds on the blocking pool).
/// Every in-process editor shares one runtime, so that a new session (a
/// fuzz input, a property-test case) costs no threads.
pub struct InProcessEditor {
    service: TowerToHyperService<axum::Router>,
    token: String,
}

/// The runtime of every in-process editor, built on first use.
fn runtime() -> Result<&'static tokio::runtime::Runtime, Error> {
    static RUNTIME: OnceLock<Result<tokio::runtime::Runtime, String>> = OnceLock::new();
    RUNTIME
        .get_or_init(|| {
            tokio::runtime::Builder::new_multi_thread()
                .worker_threads(1)
                .enable_all()
                .build()
                .map_err(|e| e.to_string())
        })
        .as_ref()
        .map_err(|e| {
            Error::io(
                "the in-process editor's runtime",
                std::io::Error::other(e.clone()),
            )
        })
}

impl InProcessEditor {
    /// A session on `mesh` (named `options.mesh` in `/api/mesh`), with
    /// `constraints` installed when given, `token` as its token and the
    /// body limit and timeout of `options` (its host, port and idle
    /// timeout are not used).
    pub fn new(
        mesh: Mesh,
        constraints: Option<ConstraintSet>,
        options: &EditOptions,
        token: String,
    ) -> Result<InProcessEditor, Error> {
        guard::check_token(&token)
            .map_err(|message| Error::from(ProblemError::InvalidArgument { message }))?;
        let app = App::new(mesh, options);
        if let Some(c) = constraints {
            app.rebuild(Change::Constraints(c))?;
        }
        let address: SocketAddr = ADDRESS.parse().expect("a socket address");
        let guard = guard::Guard::new(address, "127.0.0.1", token.clone(), PUBLIC);
        runtime()?;
        Ok(InProcessEditor {
            service: TowerToHyperService::new(router(app, guard)),
            token,
        })
    }

    /// The session token.
    pub fn token(&self) -> &str {
        &self.token
    }

    /// The answer to `request`, body collected.
    pub fn answer(&self, request: Request<Body>) -> Answer {
        let runtime = runtime().expect("built by InProcessEditor::new");
        runtime.block_on(async {
            let response = match self.service.call(request).await {
                Ok(r) => r,
                Err(never) => match never {},
            };
            let (parts, body) = response.into_parts();
            let body = axum::body::to_bytes(body, usize::MAX)
                .await
                .unwrap_or_else(|e| Bytes::from(format!("body error: {e}")));
            Answer {
                status: parts.status,
                headers: parts.headers,
                body,
            }
        })
    }

    /// A request with the session's token and a `Host` the guard accepts:
    /// what the page sends (`body` is JSON when not empty).
    pub fn request(&self, method: &str, path: &str, body: impl Into<Body>) -> Request<Body> {
        Request::builder()
            .method(method)
            .uri(path)
            .header("host", ADDRESS)
            .header("authorization", format!("Bearer {}", self.token))
            .header("content-type", "application/json")
            .body(body.into())
            .expect("a valid request")
    }
}
