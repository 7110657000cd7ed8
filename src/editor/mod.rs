//! `lse-deform edit`: the interactive editor — an HTTP server (axum on
//! tokio) serving an embedded page (WebGL2, ES modules, no build step) and
//! the JSON/binary API it uses. A front door: it translates requests into
//! calls of [`crate::Deformer`], [`crate::handle::HandleBasis`] and
//! [`crate::arap::ArapDeformer`] ([`session`]) and holds no numerics.
//!
//! Safety: only the embedded assets are served (a URL path is looked up in
//! a fixed table, never on the filesystem); request bodies are capped
//! (413 with the limit); malformed requests get 400 with `{"error": …}`
//! (the CLI's one-line message); one editing state behind a lock, every
//! update serialised; precomputes run on blocking threads, so the server
//! answers (progress, positions) meanwhile, and finish even if the client
//! disconnects.
//!
//! API (JSON unless stated): `PUT /api/constraints` (the constraints file
//! format; answer: the report), `POST /api/transform`
//! (`{"group", "matrix": 3×4 row-major}`; answer: the frame's path and
//! seconds), `GET /api/positions?format=f32|f64` (binary little-endian,
//! n × 3 row-major), `GET /api/report`, `GET /api/mesh` (counts, bounding
//! box), `GET /api/faces` (u32 little-endian, m × 3), `GET
//! /api/rest-positions` (f32), `GET /api/constraints`, `GET
//! /api/deformed.obj`, `PUT /api/settings` (any of the [`Settings`]
//! fields), `POST /api/iterate` (`{"iterations": n}`, ARAP), `GET
//! /api/progress`.

pub mod session;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

use axum::Router;
use axum::body::Bytes;
use axum::extract::rejection::{BytesRejection, QueryRejection};
use axum::extract::{DefaultBodyLimit, Query, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post, put};
use serde::Deserialize;
use serde_json::{Value, json};

use crate::constraints::{ConstraintSet, parse_constraints, read_constraints_file};
use crate::deform::Affine;
use crate::error::Error;
use crate::mesh::{self, Mesh};
pub use session::{Session, Settings};

/// Default cap on a request body: 256 MiB (a constraint on every vertex of
/// a half-million-vertex mesh is about 60 MB of JSON).
pub const DEFAULT_MAX_BODY_BYTES: usize = 256 << 20;

/// The options of `lse-deform edit`.
#[derive(Debug, Clone)]
pub struct EditOptions {
    /// The mesh file.
    pub mesh: PathBuf,
    /// A constraints file to start with.
    pub constraints: Option<PathBuf>,
    /// The address to bind.
    pub host: String,
    /// The port (0: any free port).
    pub port: u16,
    /// The cap on request bodies.
    pub max_body_bytes: usize,
}

/// The embedded page: (URL path, content type, bytes).
const ASSETS: &[(&str, &str, &[u8])] = &[
    (
        "/",
        "text/html; charset=utf-8",
        include_bytes!("assets/index.html"),
    ),
    (
        "/main.js",
        "text/javascript; charset=utf-8",
        include_bytes!("assets/main.js"),
    ),
    (
        "/view.js",
        "text/javascript; charset=utf-8",
        include_bytes!("assets/view.js"),
    ),
    (
        "/api.js",
        "text/javascript; charset=utf-8",
        include_bytes!("assets/api.js"),
    ),
];

/// The shared state of the server.
#[derive(Clone)]
struct App {
    session: Arc<Mutex<Session>>,
    /// Serialises rebuilds (constraints, settings).
    build: Arc<Mutex<()>>,
    progress: Arc<Mutex<Progress>>,
    mesh_info: Arc<Value>,
    faces: Arc<Vec<u8>>,
    max_body_bytes: usize,
}

#[derive(Default)]
struct Progress {
    stage: Option<String>,
    started: Option<Instant>,
}

/// A poisoned lock still holds a consistent state here (every update is
/// checked before it is applied), so it is taken as it is.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// An API error: a status and `{"error": message}`.
struct ApiError(StatusCode, String);

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.0, axum::Json(json!({"error": self.1}))).into_response()
    }
}

impl From<Error> for ApiError {
    fn from(e: Error) -> Self {
        let status = match e {
            Error::Numerical(_) => StatusCode::UNPROCESSABLE_ENTITY,
            _ => StatusCode::BAD_REQUEST,
        };
        ApiError(status, e.to_string())
    }
}

fn bad(message: impl Into<String>) -> ApiError {
    ApiError(StatusCode::BAD_REQUEST, message.into())
}

type ApiResult<T> = Result<T, ApiError>;

/// Reads the mesh (and constraints), binds, prints `listening on
/// http://HOST:PORT/` as the first line on stdout and serves until the
/// process is stopped.
pub fn run(options: EditOptions) -> Result<(), Error> {
    let loaded = mesh::read_mesh(&options.mesh)?;
    for note in &loaded.notes {
        eprintln!("note: {note}");
    }
    let mesh = loaded.mesh;
    let app = App::new(mesh, &options.mesh, options.max_body_bytes);
    if let Some(path) = &options.constraints {
        let constraints = read_constraints_file(path)?;
        app.rebuild(Some(constraints), None)?;
    }
    if options.host != "127.0.0.1" {
        eprintln!(
            "warning: binding {} rather than 127.0.0.1: the editor has no authentication, and anyone who can reach this address can edit",
            options.host
        );
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| Error::io(&options.mesh, e))?;
    runtime.block_on(serve(app, &options.host, options.port))
}

async fn serve(app: App, host: &str, port: u16) -> Result<(), Error> {
    let io = |e| Error::io(format!("{host}:{port}"), e);
    let listener = tokio::net::TcpListener::bind((host, port))
        .await
        .map_err(io)?;
    let addr: SocketAddr = listener.local_addr().map_err(io)?;
    println!("listening on http://{addr}/");
    use std::io::Write;
    let _ = std::io::stdout().flush();
    axum::serve(listener, router(app)).await.map_err(io)
}

fn router(app: App) -> Router {
    let limit = app.max_body_bytes;
    Router::new()
        .route("/", get(asset))
        .route("/{file}", get(asset))
        .route(
            "/api/constraints",
            put(put_constraints).get(get_constraints),
        )
        .route("/api/settings", put(put_settings))
        .route("/api/transform", post(post_transform))
        .route("/api/iterate", post(post_iterate))
        .route("/api/positions", get(get_positions))
        .route("/api/rest-positions", get(get_rest_positions))
        .route("/api/faces", get(get_faces))
        .route("/api/report", get(get_report))
        .route("/api/mesh", get(get_mesh))
        .route("/api/progress", get(get_progress))
        .route("/api/deformed.obj", get(get_deformed_obj))
        .fallback(|| async { ApiError(StatusCode::NOT_FOUND, "no such route".into()) })
        .layer(DefaultBodyLimit::max(limit))
        .with_state(app)
}

impl App {
    fn new(mesh: Mesh, path: &Path, max_body_bytes: usize) -> App {
        let (lo, hi) = bbox(mesh.positions());
        let mesh_info = json!({
            "name": path.file_name().map(|s| s.to_string_lossy().into_owned()),
            "vertices": mesh.n_vertices(),
            "faces": mesh.faces().len(),
            "bbox": {"min": lo, "max": hi},
            "diagonal": mesh.bbox_diagonal(),
        });
        let faces = mesh
            .faces()
            .iter()
            .flatten()
            .flat_map(|&v| (v as u32).to_le_bytes())
            .collect();
        App {
            session: Arc::new(Mutex::new(Session::new(mesh))),
            build: Arc::new(Mutex::new(())),
            progress: Arc::new(Mutex::new(Progress::default())),
            mesh_info: Arc::new(mesh_info),
            faces: Arc::new(faces),
            max_body_bytes,
        }
    }

    /// Precomputes new constraints and/or settings (the current ones where
    /// `None`) and installs them; on error the state stays as it was.
    /// Blocking: call on a blocking thread.
    fn rebuild(
        &self,
        constraints: Option<ConstraintSet>,
        settings: Option<Settings>,
    ) -> Result<Value, Error> {
        let _serial = lock(&self.build);
        let (mesh, constraints, settings) = {
            let s = lock(&self.session);
            (
                s.mesh.clone(),
                constraints.unwrap_or_else(|| s.constraints.clone()),
                settings.unwrap_or_else(|| s.settings.clone()),
            )
        };
        settings.check()?;
        constraints.check_vertices(mesh.n_vertices())?;
        if constraints.is_empty() {
            let mut s = lock(&self.session);
            s.settings = settings;
            s.clear();
            return Ok(s.report());
        }
        let progress = self.progress.clone();
        let stage = |name: &str| {
            let mut p = lock(&progress);
            p.stage = Some(name.to_string());
            p.started.get_or_insert_with(Instant::now);
        };
        let built = session::build(&mesh, &constraints, &settings, &stage);
        *lock(&self.progress) = Progress::default();
        let built = built?;
        let mut s = lock(&self.session);
        s.install(constraints, settings, built);
        Ok(s.report())
    }
}

fn bbox(p: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for q in p {
        for c in 0..3 {
            lo[c] = lo[c].min(q[c]);
            hi[c] = hi[c].max(q[c]);
        }
    }
    (lo, hi)
}

/// Runs `f` on a blocking thread (it finishes even if the client goes).
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> ApiResult<T> + Send + 'static,
) -> ApiResult<T> {
    tokio::task::spawn_blocking(f).await.map_err(|e| {
        ApiError(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("internal error: {e}"),
        )
    })?
}

/// The body, or 413 stating the limit / 400.
fn body(app: &App, body: Result<Bytes, BytesRejection>) -> ApiResult<Bytes> {
    body.map_err(|r| {
        if r.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError(
                StatusCode::PAYLOAD_TOO_LARGE,
                format!(
                    "request body exceeds the limit of {} bytes",
                    app.max_body_bytes
                ),
            )
        } else {
            bad(format!("could not read the request body: {r}"))
        }
    })
}

fn json_body<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> ApiResult<T> {
    serde_json::from_slice(bytes).map_err(|e| bad(format!("invalid JSON body: {e}")))
}

async fn asset(uri: axum::http::Uri) -> Response {
    match ASSETS.iter().find(|(path, _, _)| *path == uri.path()) {
        Some((_, mime, bytes)) => (
            [
                (header::CONTENT_TYPE, *mime),
                (header::CACHE_CONTROL, "no-cache"),
            ],
            *bytes,
        )
            .into_response(),
        None => ApiError(StatusCode::NOT_FOUND, "no such page".into()).into_response(),
    }
}

async fn put_constraints(
    State(app): State<App>,
    b: Result<Bytes, BytesRejection>,
) -> ApiResult<axum::Json<Value>> {
    let bytes = body(&app, b)?;
    let text = std::str::from_utf8(&bytes)
        .map_err(|e| bad(format!("constraints: the body is not UTF-8: {e}")))?;
    let constraints = parse_constraints(text).map_err(Error::from)?;
    let report =
        blocking(move || app.rebuild(Some(constraints), None).map_err(ApiError::from)).await?;
    Ok(axum::Json(report))
}

async fn put_settings(
    State(app): State<App>,
    b: Result<Bytes, BytesRejection>,
) -> ApiResult<axum::Json<Value>> {
    let bytes = body(&app, b)?;
    let changes: Value = json_body(&bytes)?;
    let Value::Object(changes) = changes else {
        return Err(bad("settings: expected a JSON object"));
    };
    let report = blocking(move || {
        let mut current = serde_json::to_value(&lock(&app.session).settings).unwrap_or(Value::Null);
        for (k, v) in changes {
            current[k] = v;
        }
        let settings: Settings =
            serde_json::from_value(current).map_err(|e| bad(format!("settings: {e}")))?;
        app.rebuild(None, Some(settings)).map_err(ApiError::from)
    })
    .await?;
    Ok(axum::Json(report))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TransformRequest {
    group: String,
    matrix: Affine,
}

async fn post_transform(
    State(app): State<App>,
    b: Result<Bytes, BytesRejection>,
) -> ApiResult<axum::Json<Value>> {
    let bytes = body(&app, b)?;
    let request: TransformRequest = json_body(&bytes)?;
    blocking(move || {
        let t = Instant::now();
        let mut s = lock(&app.session);
        let (path, compute_s) = s.transform(&request.group, &request.matrix)?;
        Ok(axum::Json(json!({
            "path": path,
            "compute_s": compute_s,
            "request_s": t.elapsed().as_secs_f64(),
            "generation": s.generation,
        })))
    })
    .await
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IterateRequest {
    iterations: usize,
}

async fn post_iterate(
    State(app): State<App>,
    b: Result<Bytes, BytesRejection>,
) -> ApiResult<axum::Json<Value>> {
    let bytes = body(&app, b)?;
    let request: IterateRequest = json_body(&bytes)?;
    if request.iterations > 1000 {
        return Err(bad(format!(
            "iterations {} must be ≤ 1000",
            request.iterations
        )));
    }
    blocking(move || {
        let n = lock(&app.session).iterate(request.iterations)?;
        Ok(axum::Json(json!({"iterations": n})))
    })
    .await
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FormatQuery {
    format: Option<String>,
}

fn encode(positions: &[[f64; 3]], format: Option<&str>) -> ApiResult<Vec<u8>> {
    match format.unwrap_or("f32") {
        "f32" => Ok(positions
            .iter()
            .flatten()
            .flat_map(|&v| (v as f32).to_le_bytes())
            .collect()),
        "f64" => Ok(positions
            .iter()
            .flatten()
            .flat_map(|&v| v.to_le_bytes())
            .collect()),
        other => Err(bad(format!(
            "unknown format '{other}' (expected f32 or f64)"
        ))),
    }
}

fn binary(bytes: Vec<u8>) -> Response {
    ([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response()
}

async fn get_positions(
    State(app): State<App>,
    q: Result<Query<FormatQuery>, QueryRejection>,
) -> ApiResult<Response> {
    let Query(q) = q.map_err(|e| bad(format!("query: {e}")))?;
    blocking(move || {
        let s = lock(&app.session);
        Ok(binary(encode(&s.positions, q.format.as_deref())?))
    })
    .await
}

async fn get_rest_positions(
    State(app): State<App>,
    q: Result<Query<FormatQuery>, QueryRejection>,
) -> ApiResult<Response> {
    let Query(q) = q.map_err(|e| bad(format!("query: {e}")))?;
    blocking(move || {
        let s = lock(&app.session);
        Ok(binary(encode(s.mesh.positions(), q.format.as_deref())?))
    })
    .await
}

async fn get_faces(State(app): State<App>) -> Response {
    binary(app.faces.as_ref().clone())
}

async fn get_report(State(app): State<App>) -> ApiResult<axum::Json<Value>> {
    blocking(move || Ok(axum::Json(lock(&app.session).report()))).await
}

async fn get_mesh(State(app): State<App>) -> axum::Json<Value> {
    axum::Json(app.mesh_info.as_ref().clone())
}

async fn get_progress(State(app): State<App>) -> axum::Json<Value> {
    let p = lock(&app.progress);
    axum::Json(json!({
        "busy": p.stage.is_some(),
        "stage": p.stage,
        "elapsed_s": p.started.map(|t| t.elapsed().as_secs_f64()),
    }))
}

async fn get_constraints(State(app): State<App>) -> ApiResult<Response> {
    blocking(move || {
        let json = lock(&app.session).constraints.to_json();
        Ok(([(header::CONTENT_TYPE, "application/json")], json).into_response())
    })
    .await
}

async fn get_deformed_obj(State(app): State<App>) -> ApiResult<Response> {
    blocking(move || {
        let s = lock(&app.session);
        let deformed = s
            .mesh
            .with_positions(s.positions.clone())
            .map_err(Error::from)?;
        let mut out = Vec::new();
        mesh::io::write_obj(&deformed, &mut out).map_err(|e| Error::io("deformed.obj", e))?;
        Ok(([(header::CONTENT_TYPE, "text/plain; charset=utf-8")], out).into_response())
    })
    .await
}
