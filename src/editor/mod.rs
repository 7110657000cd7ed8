//! `lse-deform edit`: the interactive editor — an HTTP server (axum on
//! tokio, hyper's connections) serving an embedded page (WebGL2, ES
//! modules, no build step) and the JSON/binary API it uses. A front door:
//! it translates requests into calls of [`crate::Deformer`],
//! [`crate::handle::HandleBasis`] and [`crate::arap::ArapDeformer`]
//! ([`session`]) and holds no numerics.
//!
//! A careful local web service ([`guard`], [`conn`]): a per-session token
//! (`listening on http://HOST:PORT/?token=T`; every API request carries
//! `Authorization: Bearer T` or `?token=T`, 401 otherwise); `Host` checked
//! against the bound address and name (403: DNS rebinding); cross-origin
//! requests (`Origin`, `Sec-Fetch-Site`) refused with 403; `POST`/`PUT`
//! bodies only as `application/json` (415); a request body must arrive
//! within the body timeout (408) and stay under the cap (413, at once when
//! `Content-Length` says so); idle connections closed after the idle
//! timeout; URIs above 8 KiB get 414; every error answer is `{"error":
//! message, "kind": word}` (the CLI's one-line message); only the embedded
//! assets are served (a URL path is looked up in a fixed table, never on
//! the filesystem).
//!
//! One editing state behind a lock; a change of constraints or settings is
//! one read-modify-write under the build lock, so concurrent changes all
//! take effect; parsing, precomputes and every request touching the state
//! run on the blocking pool, so the async workers answer
//! (`/api/progress`, `/api/report`) meanwhile, and a precompute finishes
//! even if the client disconnects. Positions are checked finite in the
//! format sent: a transform that would put a group's targets beyond the
//! range of f32 is refused (422, `kind` `not-representable`, nothing
//! changes), and `GET /api/positions?format=f32` answers 422 rather than
//! send `inf`. A change whose work would not fit is refused before it
//! starts with 413 (`kind` `too-large`, nothing changed, progress idle):
//! a response basis of more than [`session::MAX_BASIS_GROUPS`] groups or
//! beyond the memory budget ([`crate::limits`]), a factor beyond it.
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
//! /api/progress`, `GET /api/basis` (below).
//!
//! `GET /api/basis` (binary, little-endian): the response basis
//! `X = X₀ + Σ_g R_g M_gᵀ` once, in f32, for a page that evaluates frames
//! itself. A u32 `h`, then `h` bytes of UTF-8 JSON (padded with spaces to
//! a multiple of 4: `{"vertices": n, "groups": [names, in the order of
//! the texels], "generation", "texels_per_vertex": 1 + G}`), then
//! `n × (1 + G)` texels of four f32: per vertex `(X₀x, X₀y, X₀z, 0)` and,
//! per group `g`, the four columns of row `v` of `R_g` (n × 4), so that
//! vertex `v`'s position is `X₀ + Σ_g M_g r_g` with `M_g` the group's 3 × 4
//! transform as `POST /api/transform` takes it. 409 (`kind` `no-basis`)
//! when no basis describes the positions (ARAP, no movable group, a group
//! outside the basis moved); 413 beyond the memory budget.

mod api_error;
pub mod conn;
pub mod guard;
pub mod in_process;
pub mod session;
mod unique_json;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use axum::Router;
use axum::body::{Body, Bytes, HttpBody};
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, Request, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post, put};
use serde::Deserialize;
use serde_json::{Map, Value, json};

use crate::choice::Word;
use crate::constraints::{ConstraintSet, parse_constraints, read_constraints_file};
use crate::deform::Affine;
use crate::error::{Error, ParseWordError, ProblemError};
use crate::handle::HandleBasis;
use crate::mesh::{self, Mesh};
pub use api_error::ApiError;
use api_error::{ApiResult, bad};
use session::Engine;
pub use session::{FrameError, Session, Settings};

/// Default cap on a request body: 256 MiB (a constraint on every vertex of
/// a half-million-vertex mesh is about 60 MB of JSON).
pub const DEFAULT_MAX_BODY_BYTES: usize = 256 << 20;

/// Default time for a request body to arrive after its head.
pub const DEFAULT_BODY_TIMEOUT: Duration = Duration::from_secs(60);

/// Default time a connection may stay idle (or take for a request head)
/// before it is closed.
pub const DEFAULT_IDLE_TIMEOUT: Duration = Duration::from_secs(30);

/// The environment variable that may hold the session token.
pub const TOKEN_ENV: &str = "LSE_DEFORM_EDIT_TOKEN";

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
    /// The session token (`None`: 32 random bytes in hex).
    pub token: Option<String>,
    /// The time a request body has to arrive (408 beyond).
    pub body_timeout: Duration,
    /// The time a connection may stay idle before it is closed.
    pub idle_timeout: Duration,
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

/// The URL paths of [`ASSETS`]: the only ones served without the token.
const PUBLIC: &[&str] = &["/", "/main.js", "/view.js", "/api.js"];

/// The shared state of the server.
#[derive(Clone)]
struct App {
    session: Arc<Mutex<Session>>,
    /// Serialises changes of constraints and settings (each one
    /// read-modify-write).
    build: Arc<Mutex<()>>,
    progress: Arc<Mutex<Progress>>,
    mesh_info: Arc<Value>,
    faces: Arc<Vec<u8>>,
    max_body_bytes: usize,
    body_timeout: Duration,
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

/// Reads the mesh (and constraints), binds, prints `listening on
/// http://HOST:PORT/?token=T` as the first line on stdout and serves until
/// the process is stopped.
pub fn run(options: EditOptions) -> Result<(), Error> {
    let invalid = |message| Error::from(ProblemError::InvalidArgument { message });
    let token = match options.token.clone() {
        Some(t) => {
            guard::check_token(&t).map_err(invalid)?;
            t
        }
        None => guard::random_token().map_err(invalid)?,
    };
    for (name, t) in [
        ("--body-timeout", options.body_timeout),
        ("--idle-timeout", options.idle_timeout),
    ] {
        if t.is_zero() {
            return Err(invalid(format!("{name} must be positive")));
        }
    }
    let loaded = mesh::read_mesh(&options.mesh, crate::limits::MemoryBudget::default())?;
    for note in &loaded.notes {
        eprintln!("note: {note}");
    }
    let mesh = loaded.mesh;
    let app = App::new(mesh, &options);
    if let Some(path) = &options.constraints {
        let constraints = read_constraints_file(path, crate::limits::MemoryBudget::default())?;
        app.rebuild(Change::Constraints(constraints))?;
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| Error::io(&options.mesh, e))?;
    runtime.block_on(serve(app, &options, token))
}

async fn serve(app: App, options: &EditOptions, token: String) -> Result<(), Error> {
    let (host, port) = (options.host.as_str(), options.port);
    let io = |e| Error::io(format!("{host}:{port}"), e);
    let listener = tokio::net::TcpListener::bind((host, port))
        .await
        .map_err(io)?;
    let addr: SocketAddr = listener.local_addr().map_err(io)?;
    if !addr.ip().is_loopback() {
        eprintln!(
            "warning: listening on {addr}, not a loopback address: anyone who can reach it and learns the token can edit, and plain HTTP carries the token unencrypted"
        );
    }
    let guard = guard::Guard::new(addr, host, token.clone(), PUBLIC);
    println!("listening on http://{addr}/?token={token}");
    use std::io::Write;
    let _ = std::io::stdout().flush();
    conn::serve(listener, router(app, guard), options.idle_timeout).await;
    Ok(())
}

/// The routes, inside the guard (wrapping the whole router, so that it
/// sees every answer whole, axum's 405 with its `Allow` too).
fn router(app: App, guard: guard::Guard) -> Router {
    let routes = Router::new()
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
        .route("/api/basis", get(get_basis))
        .route("/api/rest-positions", get(get_rest_positions))
        .route("/api/faces", get(get_faces))
        .route("/api/report", get(get_report))
        .route("/api/mesh", get(get_mesh))
        .route("/api/progress", get(get_progress))
        .route("/api/deformed.obj", get(get_deformed_obj))
        .fallback(|| async {
            ApiError::new(StatusCode::NOT_FOUND, "not-found", "no such route".into())
        })
        .with_state(app);
    Router::new()
        .fallback_service(routes)
        .layer(axum::middleware::from_fn_with_state(guard, guard::check))
}

/// A change of the editing state that needs a new precompute.
enum Change {
    /// New constraints (the settings kept).
    Constraints(ConstraintSet),
    /// Some settings fields (the others and the constraints kept).
    Settings(Map<String, Value>),
}

impl App {
    fn new(mesh: Mesh, options: &EditOptions) -> App {
        let (lo, hi) = bbox(mesh.positions());
        let path: &Path = &options.mesh;
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
            max_body_bytes: options.max_body_bytes,
            body_timeout: options.body_timeout,
        }
    }

    /// Applies `change` to the current constraints and settings, read
    /// under the build lock (so a concurrent change is never lost),
    /// precomputes and installs the result; on error the state stays as it
    /// was. Blocking: call on a blocking thread.
    fn rebuild(&self, change: Change) -> Result<Value, Error> {
        let _serial = lock(&self.build);
        let (mesh, constraints, settings) = {
            let s = lock(&self.session);
            let (constraints, settings) = match change {
                Change::Constraints(c) => (c, s.settings.clone()),
                Change::Settings(fields) => (s.constraints.clone(), s.settings.with(fields)?),
            };
            (s.mesh.clone(), constraints, settings)
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
        // Idle again however the build ends (an error, or a panic that
        // would otherwise leave `/api/progress` busy for good).
        let built = {
            let _idle = IdleOnDrop(&self.progress);
            session::build(&mesh, &constraints, &settings, &stage)
        }?;
        let mut s = lock(&self.session);
        s.install(constraints, settings, built);
        Ok(s.report())
    }
}

/// Resets the progress when dropped.
struct IdleOnDrop<'a>(&'a Mutex<Progress>);

impl Drop for IdleOnDrop<'_> {
    fn drop(&mut self) {
        *lock(self.0) = Progress::default();
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
        ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "internal",
            format!("internal error: {e}"),
        )
    })?
}

/// The body of `request`: 413 stating the limit (at once when
/// `Content-Length` exceeds it), 408 when it has not arrived within the
/// body timeout, 400 when the connection fails.
async fn read_body(app: &App, request: Request) -> ApiResult<Bytes> {
    let limit = app.max_body_bytes;
    let too_large = || {
        ApiError::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            "too-large",
            format!("request body exceeds the limit of {limit} bytes"),
        )
    };
    let declared = request
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok());
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(too_large());
    }
    let mut body: Body = request.into_body();
    let collect = async {
        let mut out = Vec::new();
        while let Some(frame) = std::future::poll_fn(|cx| Pin::new(&mut body).poll_frame(cx)).await
        {
            let frame = frame.map_err(|e| bad(format!("could not read the request body: {e}")))?;
            if let Ok(data) = frame.into_data() {
                if out.len() + data.len() > limit {
                    return Err(too_large());
                }
                out.extend_from_slice(&data);
            }
        }
        Ok(Bytes::from(out))
    };
    tokio::time::timeout(app.body_timeout, collect)
        .await
        .unwrap_or_else(|_| {
            Err(ApiError::new(
                StatusCode::REQUEST_TIMEOUT,
                "timeout",
                format!(
                    "the request body did not arrive within {} s",
                    app.body_timeout.as_secs_f64()
                ),
            ))
        })
}

fn json_body<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> ApiResult<T> {
    serde_json::from_slice(bytes).map_err(|e| bad(format!("invalid JSON body: {e}")))
}

async fn asset(uri: axum::http::Uri) -> Response {
    match ASSETS.iter().find(|(path, _, _)| *path == uri.path()) {
        // Not framed by another site, not sniffed as another type, and the
        // page's URL (with its token until the page drops it) not sent on.
        Some((_, mime, bytes)) => (
            [
                (header::CONTENT_TYPE, *mime),
                (header::CACHE_CONTROL, "no-cache"),
                (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
                (header::CONTENT_SECURITY_POLICY, "frame-ancestors 'none'"),
                (header::REFERRER_POLICY, "no-referrer"),
            ],
            *bytes,
        )
            .into_response(),
        None => {
            ApiError::new(StatusCode::NOT_FOUND, "not-found", "no such page".into()).into_response()
        }
    }
}

async fn put_constraints(State(app): State<App>, request: Request) -> ApiResult<axum::Json<Value>> {
    let bytes = read_body(&app, request).await?;
    let report = blocking(move || {
        let text = std::str::from_utf8(&bytes)
            .map_err(|e| bad(format!("constraints: the body is not UTF-8: {e}")))?;
        let constraints = parse_constraints(text).map_err(Error::from)?;
        drop(bytes);
        Ok(app.rebuild(Change::Constraints(constraints))?)
    })
    .await?;
    Ok(axum::Json(report))
}

async fn put_settings(State(app): State<App>, request: Request) -> ApiResult<axum::Json<Value>> {
    let bytes = read_body(&app, request).await?;
    let report = blocking(move || {
        // A repeated field is refused, as in a constraints file (a `Value`
        // keeps the last).
        let unique_json::UniqueKeys(Value::Object(fields)) = json_body(&bytes)? else {
            return Err(bad("settings: expected a JSON object"));
        };
        Ok(app.rebuild(Change::Settings(fields))?)
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

async fn post_transform(State(app): State<App>, request: Request) -> ApiResult<axum::Json<Value>> {
    let bytes = read_body(&app, request).await?;
    blocking(move || {
        let request: TransformRequest = json_body(&bytes)?;
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

async fn post_iterate(State(app): State<App>, request: Request) -> ApiResult<axum::Json<Value>> {
    let bytes = read_body(&app, request).await?;
    blocking(move || {
        let request: IterateRequest = json_body(&bytes)?;
        if request.iterations > 1000 {
            return Err(bad(format!(
                "iterations {} must be ≤ 1000",
                request.iterations
            )));
        }
        let n = lock(&app.session).iterate(request.iterations)?;
        Ok(axum::Json(json!({"iterations": n})))
    })
    .await
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FormatQuery {
    /// Parsed into [`PositionFormat`] by [`FormatQuery::format`].
    format: Option<String>,
}

impl FormatQuery {
    /// The format asked for; absent: [`PositionFormat::default`].
    ///
    /// Errors: 400 with the [`ParseWordError`] listing the formats.
    fn format(&self) -> ApiResult<PositionFormat> {
        self.format
            .as_deref()
            .map_or(Ok(PositionFormat::default()), |w| {
                w.parse().map_err(|e: ParseWordError| bad(e.to_string()))
            })
    }
}

/// The number format of `GET /api/positions`: little-endian IEEE floats of
/// 4 or 8 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PositionFormat {
    /// `f32` (the default: what WebGL draws).
    #[default]
    F32,
    /// `f64` (the positions as computed).
    F64,
}

impl Word for PositionFormat {
    const WHAT: &'static str = "format";
    fn all() -> &'static [Self] {
        &[PositionFormat::F32, PositionFormat::F64]
    }
    fn name(self) -> &'static str {
        match self {
            PositionFormat::F32 => "f32",
            PositionFormat::F64 => "f64",
        }
    }
}

crate::choice::word_traits!(PositionFormat);

/// `positions` little-endian in `format`; 422 when a value is not finite
/// in that format (a coordinate beyond ±3.4e38 in f32) rather than send it.
fn encode(positions: &[[f64; 3]], format: PositionFormat) -> ApiResult<Vec<u8>> {
    let finite: fn(f64) -> bool = match format {
        PositionFormat::F32 => {
            let mut out = Vec::with_capacity(positions.len() * 12);
            let mut all_finite = true;
            for &v in positions.iter().flatten() {
                let x = v as f32;
                all_finite &= x.is_finite();
                out.extend_from_slice(&x.to_le_bytes());
            }
            if all_finite {
                return Ok(out);
            }
            |v: f64| (v as f32).is_finite()
        }
        PositionFormat::F64 => {
            if positions.iter().flatten().all(|v| v.is_finite()) {
                return Ok(positions
                    .iter()
                    .flatten()
                    .flat_map(|&v| v.to_le_bytes())
                    .collect());
            }
            f64::is_finite
        }
    };
    let (vertex, p) = positions
        .iter()
        .enumerate()
        .find(|(_, p)| !p.iter().all(|&v| finite(v)))
        .expect("a value that is not finite");
    Err(ApiError::new(
        StatusCode::UNPROCESSABLE_ENTITY,
        "not-representable",
        format!(
            "vertex {vertex} at {p:?} is not finite in {format}{}",
            if format == PositionFormat::F32 {
                " (beyond ±3.4e38): ask for format=f64"
            } else {
                ""
            }
        ),
    ))
}

fn binary(bytes: Vec<u8>) -> Response {
    ([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response()
}

async fn get_positions(
    State(app): State<App>,
    q: Result<Query<FormatQuery>, QueryRejection>,
) -> ApiResult<Response> {
    let Query(q) = q.map_err(|e| bad(format!("query: {e}")))?;
    let format = q.format()?;
    blocking(move || {
        let s = lock(&app.session);
        Ok(binary(encode(&s.positions, format)?))
    })
    .await
}

/// Bytes of the `GET /api/basis` body for `n` vertices and `groups`
/// groups besides its JSON head: `16 n (1 + groups)` (one RGBA32F texel
/// for `X₀` and one per group for `R_g`), held once while it is built.
pub(crate) fn basis_response_bytes(n: usize, groups: usize) -> u64 {
    16u64
        .saturating_mul(n as u64)
        .saturating_mul(1 + groups as u64)
}

/// The body of `GET /api/basis` (layout in the module documentation and
/// docs/editor.md §6): the u32 length `h` of a JSON head padded with spaces to a
/// multiple of 4 bytes, the head, then per vertex `(X₀, 0)` and each
/// group's four columns of `R_g` as f32, little-endian. The size is checked
/// against the memory budget first (413); an entry beyond f32 is refused
/// (422) rather than sent as `inf`.
fn encode_basis(basis: &HandleBasis, generation: u64) -> ApiResult<Vec<u8>> {
    let (n, groups) = (basis.n_vertices(), basis.groups().len());
    let bytes = basis_response_bytes(n, groups);
    crate::limits::check(bytes, || {
        format!("the f32 response basis of {groups} group(s) on {n} vertices would need")
    })
    .map_err(|detail| Error::from(ProblemError::TooLarge { detail }))?;
    let mut head = json!({
        "vertices": n,
        "groups": basis.groups(),
        "generation": generation,
        "texels_per_vertex": 1 + groups,
    })
    .to_string();
    while !head.len().is_multiple_of(4) {
        head.push(' ');
    }
    let mut out = Vec::with_capacity(4 + head.len() + bytes as usize);
    out.extend_from_slice(&(head.len() as u32).to_le_bytes());
    out.extend_from_slice(head.as_bytes());
    let columns = 3 + 4 * groups;
    for v in 0..n {
        for j in (0..3).chain(std::iter::once(usize::MAX)).chain(3..columns) {
            let x = if j == usize::MAX {
                0.0
            } else {
                basis.entry(v, j) as f32
            };
            if !x.is_finite() {
                return Err(ApiError::new(
                    StatusCode::UNPROCESSABLE_ENTITY,
                    "not-representable",
                    format!(
                        "the response basis at vertex {v}, column {j}, is not finite in f32 (beyond ±3.4e38): use the positions"
                    ),
                ));
            }
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    Ok(out)
}

/// `GET /api/basis`: 409 (`kind` `no-basis`) when the session has no
/// response basis (ARAP, no movable group, no constraints) or a group
/// outside it has moved (the basis no longer describes the positions).
async fn get_basis(State(app): State<App>) -> ApiResult<Response> {
    blocking(move || {
        let s = lock(&app.session);
        match &s.engine {
            Some(Engine::Linear {
                basis: Some(basis),
                basis_stale: false,
                ..
            }) => Ok(binary(encode_basis(basis, s.generation)?)),
            _ => Err(ApiError::new(
                StatusCode::CONFLICT,
                "no-basis",
                "no response basis describes the positions now (ARAP energy, no movable group, or a group outside the basis moved): use POST /api/transform and GET /api/positions".into(),
            )),
        }
    })
    .await
}

async fn get_rest_positions(
    State(app): State<App>,
    q: Result<Query<FormatQuery>, QueryRejection>,
) -> ApiResult<Response> {
    let Query(q) = q.map_err(|e| bad(format!("query: {e}")))?;
    let format = q.format()?;
    blocking(move || {
        let s = lock(&app.session);
        Ok(binary(encode(s.mesh.positions(), format)?))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_beyond_f32_are_refused_not_sent_as_inf() {
        let ok = [[1.0, -2.0, 3.0e38]];
        assert_eq!(encode(&ok, PositionFormat::default()).unwrap().len(), 12);
        assert_eq!(encode(&ok, PositionFormat::F64).unwrap().len(), 24);
        let far = [[0.0; 3], [1.0, 1e39, 0.0]];
        let e = encode(&far, PositionFormat::F32).unwrap_err();
        assert_eq!(e.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(e.kind, "not-representable");
        assert!(e.message.contains("vertex 1"), "{}", e.message);
        assert_eq!(encode(&far, PositionFormat::F64).unwrap().len(), 48);
        let nan = [[f64::NAN, 0.0, 0.0]];
        let query = |w: &str| {
            FormatQuery {
                format: Some(w.into()),
            }
            .format()
        };
        assert_eq!(query("f64").unwrap(), PositionFormat::F64);
        let e = query("xyz").unwrap_err();
        assert_eq!(e.status, StatusCode::BAD_REQUEST);
        assert!(e.message.contains("'xyz'") && e.message.contains("f32, f64"));
        assert_eq!(
            encode(&nan, PositionFormat::F64).unwrap_err().kind,
            "not-representable"
        );
    }
}
