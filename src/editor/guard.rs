//! The front door's checks, which make the editor a careful local web
//! service rather than an open one: any page the user visits can send
//! requests to `127.0.0.1`, and a name the attacker controls can be
//! re-pointed there (DNS rebinding). Every request passes [`check`]:
//!
//! 1. `Host` must appear once (400 otherwise) and name this server: the
//!    bound address with its port, and
//!    for a loopback (or unspecified) address also `localhost:PORT`,
//!    `127.0.0.1:PORT` and `[::1]:PORT`, or the `--host` name with the port
//!    (an unspecified address also takes any IP literal with the port: a
//!    literal cannot be rebound) — otherwise 403.
//! 2. A request URI above [`MAX_URI_BYTES`] gets 414.
//! 3. Only `GET`/`HEAD` of the embedded page's files go without a token.
//!    Anything else (the API) is refused with 403 when `Sec-Fetch-Site`
//!    says `cross-site` or `same-site`, or when `Origin` is present and is
//!    not `http://` + this `Host`; then it needs the session's token, as
//!    `Authorization: Bearer T` or the query parameter `token=T` (compared
//!    in constant time; 401 otherwise), and a `POST`/`PUT`/`PATCH` body
//!    must be `Content-Type: application/json` (415 otherwise: a form or
//!    `text/plain` is what a cross-site page can send without asking).
//!    The `token` parameter is removed from the URI the handlers see.
//! 4. Any error answer without a JSON body (axum's own 405, say) gets
//!    `{"error", "kind"}` ([`json_errors`]).

use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, Uri, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::ApiError;

/// Request URIs above this many bytes get 414.
pub const MAX_URI_BYTES: usize = 8 << 10;

/// What a request must match: the token and the `Host` values.
#[derive(Clone)]
pub struct Guard {
    token: Arc<str>,
    /// Allowed `Host` values, lower case.
    hosts: Arc<[String]>,
    port: u16,
    /// Bound to 0.0.0.0 or `::`: any IP literal with the port is this
    /// server.
    any_ip: bool,
    /// The URL paths served without a token (`GET`/`HEAD` only).
    public: &'static [&'static str],
}

/// 32 random bytes from the operating system, in hex.
pub(crate) fn random_token() -> Result<String, String> {
    use rand::TryRngCore;
    let mut bytes = [0u8; 32];
    rand::rngs::OsRng
        .try_fill_bytes(&mut bytes)
        .map_err(|e| format!("could not draw a token from the operating system: {e}"))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// A token given by the user: 16 to 256 characters of `A-Z a-z 0-9 - . _
/// ~` (they go in a URL unescaped).
pub(crate) fn check_token(token: &str) -> Result<(), String> {
    let ok = (16..=256).contains(&token.len())
        && token
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-._~".contains(&b));
    if ok {
        Ok(())
    } else {
        Err(format!(
            "the token must be 16 to 256 characters of A-Z, a-z, 0-9, '-', '.', '_' and '~' (got {} characters)",
            token.len()
        ))
    }
}

/// Equal bytes, in a time that depends on the lengths only.
fn same_bytes(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    let diff = a.iter().zip(b).fold(0u8, |d, (x, y)| d | (x ^ y));
    std::hint::black_box(diff) == 0
}

impl Guard {
    /// The checks of a server bound at `bound`, asked for by `name` (the
    /// `--host` value), with `token`.
    pub fn new(
        bound: SocketAddr,
        name: &str,
        token: String,
        public: &'static [&'static str],
    ) -> Guard {
        let port = bound.port();
        let ip = bound.ip();
        let mut hosts = vec![bound.to_string()];
        if ip.is_loopback() || ip.is_unspecified() {
            hosts.extend([
                format!("localhost:{port}"),
                format!("127.0.0.1:{port}"),
                format!("[::1]:{port}"),
            ]);
        }
        if name.parse::<IpAddr>().is_err() {
            hosts.push(format!("{name}:{port}"));
        }
        if port == 80 {
            let bare: Vec<String> = hosts
                .iter()
                .filter_map(|h| h.strip_suffix(":80").map(str::to_string))
                .collect();
            hosts.extend(bare);
        }
        let mut hosts: Vec<String> = hosts.iter().map(|h| h.to_ascii_lowercase()).collect();
        hosts.sort();
        hosts.dedup();
        Guard {
            token: token.into(),
            hosts: hosts.into(),
            port,
            any_ip: ip.is_unspecified(),
            public,
        }
    }

    /// Whether `host` (a `Host` header) names this server.
    pub(crate) fn host_allowed(&self, host: &str) -> bool {
        let host = host.to_ascii_lowercase();
        if self.hosts.contains(&host) {
            return true;
        }
        self.any_ip
            && host
                .parse::<SocketAddr>()
                .is_ok_and(|a| a.port() == self.port)
    }

    fn token_matches(&self, candidate: &str) -> bool {
        same_bytes(candidate.as_bytes(), self.token.as_bytes())
    }

    /// Admits `request` (removing its `token` query parameter) or says why
    /// not.
    pub(crate) fn admit(&self, request: &mut Request) -> Result<(), ApiError> {
        let host = self.checked_host(request)?;
        let method = request.method();
        let public = (method == Method::GET || method == Method::HEAD)
            && self.public.contains(&request.uri().path());
        if public {
            return Ok(());
        }
        cross_origin(request.headers(), &host)?;
        self.check_token(request)?;
        if matches!(*method, Method::POST | Method::PUT | Method::PATCH) {
            json_body_type(request.headers())?;
        }
        if let Some(uri) = without_token(request.uri()) {
            *request.uri_mut() = uri;
        }
        Ok(())
    }

    /// The request's one Host, if this server answers to it (and to the
    /// authority of an absolute-form target), and a URI within
    /// [`MAX_URI_BYTES`].
    fn checked_host(&self, request: &Request) -> Result<String, ApiError> {
        let headers = request.headers();
        // RFC 9112 §3.2: a request with more than one Host line gets 400
        // (which one the server would obey is what an attacker picks).
        let hosts = headers.get_all(header::HOST).iter().count();
        if hosts > 1 {
            return Err(ApiError::new(
                StatusCode::BAD_REQUEST,
                "bad-request",
                format!("{hosts} Host headers: a request has exactly one (RFC 9112 §3.2)"),
            ));
        }
        let host = match headers.get(header::HOST).map(HeaderValue::to_str) {
            Some(Ok(h)) if self.host_allowed(h) => h.to_string(),
            other => {
                let shown = match other {
                    None => "no Host header".to_string(),
                    Some(Ok(h)) => format!("Host '{h}'"),
                    Some(Err(_)) => "a Host header that is not ASCII".to_string(),
                };
                return Err(ApiError::new(
                    StatusCode::FORBIDDEN,
                    "forbidden-host",
                    format!(
                        "{shown}: this server answers to {} only (DNS rebinding protection)",
                        self.hosts.join(", ")
                    ),
                ));
            }
        };
        // An absolute-form request target names its own authority.
        if let Some(authority) = request.uri().authority()
            && !self.host_allowed(authority.as_str())
        {
            return Err(ApiError::new(
                StatusCode::FORBIDDEN,
                "forbidden-host",
                format!("request target for '{authority}': not this server"),
            ));
        }
        let uri_len = request
            .uri()
            .path_and_query()
            .map_or(0, |p| p.as_str().len());
        if uri_len > MAX_URI_BYTES {
            return Err(ApiError::new(
                StatusCode::URI_TOO_LONG,
                "uri-too-long",
                format!("the request URI has {uri_len} bytes (limit {MAX_URI_BYTES})"),
            ));
        }
        Ok(host)
    }

    /// 401 unless the request carries the token, as a bearer or as a
    /// `token` query parameter.
    fn check_token(&self, request: &Request) -> Result<(), ApiError> {
        let bearer = request
            .headers()
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.trim().split_once(' '))
            .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
            .map(|(_, t)| t.trim());
        let query = request.uri().query().unwrap_or("");
        let mut from_query = query.split('&').filter_map(|kv| kv.strip_prefix("token="));
        let authorised = bearer.is_some_and(|t| self.token_matches(t))
            || from_query.any(|t| self.token_matches(t));
        if authorised {
            return Ok(());
        }
        let mut e = ApiError::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            if bearer.is_some() || query.split('&').any(|kv| kv.starts_with("token=")) {
                "wrong token (it is in the URL that `lse-deform edit` printed)"
            } else {
                "missing token: send 'Authorization: Bearer TOKEN' or '?token=TOKEN' (it is in the URL that `lse-deform edit` printed)"
            }
            .to_string(),
        );
        e.www_authenticate = true;
        Err(e)
    }
}

/// 415 unless the body is declared `application/json`.
fn json_body_type(headers: &HeaderMap) -> Result<(), ApiError> {
    let kind = headers
        .get(header::CONTENT_TYPE)
        .map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned());
    let json = kind.as_deref().is_some_and(|k| {
        k.split(';')
            .next()
            .is_some_and(|essence| essence.trim().eq_ignore_ascii_case("application/json"))
    });
    if json {
        return Ok(());
    }
    Err(ApiError::new(
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "unsupported-media-type",
        format!(
            "the body must be sent as 'Content-Type: application/json' (got {})",
            kind.map_or("none".to_string(), |k| format!("'{k}'"))
        ),
    ))
}

/// 403 when the browser says the request comes from another site, or its
/// `Origin` is not `http://HOST`.
fn cross_origin(headers: &HeaderMap, host: &str) -> Result<(), ApiError> {
    if let Some(site) = headers.get("sec-fetch-site") {
        let site = site.as_bytes();
        if site != b"same-origin" && site != b"none" {
            return Err(ApiError::new(
                StatusCode::FORBIDDEN,
                "cross-origin",
                format!(
                    "cross-origin request refused (Sec-Fetch-Site: {})",
                    String::from_utf8_lossy(site)
                ),
            ));
        }
    }
    if let Some(origin) = headers.get(header::ORIGIN) {
        let origin = String::from_utf8_lossy(origin.as_bytes());
        let own = format!("http://{host}");
        if !origin.eq_ignore_ascii_case(&own) {
            return Err(ApiError::new(
                StatusCode::FORBIDDEN,
                "cross-origin",
                format!("cross-origin request refused: Origin '{origin}' is not '{own}'"),
            ));
        }
    }
    Ok(())
}

/// `uri` without its `token=` query parameters (`None`: there were none).
fn without_token(uri: &Uri) -> Option<Uri> {
    let query = uri.query()?;
    if !query.split('&').any(|kv| kv.starts_with("token=")) {
        return None;
    }
    let kept: Vec<&str> = query
        .split('&')
        .filter(|kv| !kv.is_empty() && !kv.starts_with("token="))
        .collect();
    let path_and_query = if kept.is_empty() {
        uri.path().to_string()
    } else {
        format!("{}?{}", uri.path(), kept.join("&"))
    };
    let mut parts = uri.clone().into_parts();
    parts.path_and_query = Some(path_and_query.parse().ok()?);
    Uri::from_parts(parts).ok()
}

/// The middleware: [`Guard::admit`], then [`json_errors`] on the answer.
pub async fn check(State(guard): State<Guard>, mut request: Request, next: Next) -> Response {
    if let Err(e) = guard.admit(&mut request) {
        return e.into_response();
    }
    let method = request.method().clone();
    let path = request.uri().path().to_string();
    json_errors(next.run(request).await, &method, &path)
}

/// An error answer without a JSON body (axum's 405 and the like) gets one:
/// `{"error": message, "kind": …}`, its other headers kept.
pub(crate) fn json_errors(response: Response, method: &Method, path: &str) -> Response {
    let status = response.status();
    if !(status.is_client_error() || status.is_server_error()) {
        return response;
    }
    let json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"application/json"));
    if json {
        return response;
    }
    let (parts, _) = response.into_parts();
    let message = if status == StatusCode::METHOD_NOT_ALLOWED {
        let allowed = parts
            .headers
            .get(header::ALLOW)
            .map(|v| String::from_utf8_lossy(v.as_bytes()).replace(',', ", "))
            .unwrap_or_default();
        format!("{method} is not allowed on {path} (allowed: {allowed})")
    } else {
        super::api_error::status_message(status)
    };
    let mut answer =
        ApiError::new(status, super::api_error::status_kind(status), message).into_response();
    for (name, value) in &parts.headers {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            answer.headers_mut().insert(name.clone(), value.clone());
        }
    }
    answer
}

#[cfg(test)]
mod tests {
    use super::*;

    fn guard(bound: &str, name: &str) -> Guard {
        Guard::new(bound.parse().unwrap(), name, "t".repeat(32), &["/"])
    }

    #[test]
    fn hosts_of_a_loopback_server() {
        let g = guard("127.0.0.1:8080", "127.0.0.1");
        for ok in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LocalHost:8080",
            "[::1]:8080",
        ] {
            assert!(g.host_allowed(ok), "{ok}");
        }
        for refused in [
            "evil.example:8080",
            "localhost:8081",
            "127.0.0.1",
            "localhost",
            "127.0.0.2:8080",
            "localhost.:8080",
            "",
        ] {
            assert!(!g.host_allowed(refused), "{refused}");
        }
    }

    #[test]
    fn hosts_of_a_named_or_unspecified_server() {
        let g = guard("192.168.1.5:80", "box.lan");
        for ok in ["192.168.1.5:80", "192.168.1.5", "box.lan:80", "BOX.lan"] {
            assert!(g.host_allowed(ok), "{ok}");
        }
        assert!(!g.host_allowed("localhost:80"));
        assert!(!g.host_allowed("10.0.0.1:80"));
        let g = guard("0.0.0.0:9000", "0.0.0.0");
        for ok in ["10.0.0.1:9000", "[fe80::1]:9000", "localhost:9000"] {
            assert!(g.host_allowed(ok), "{ok}");
        }
        assert!(!g.host_allowed("10.0.0.1:9001"));
        assert!(!g.host_allowed("evil.example:9000"));
    }

    #[test]
    fn tokens() {
        assert!(same_bytes(b"abc", b"abc"));
        assert!(!same_bytes(b"abc", b"abd"));
        assert!(!same_bytes(b"abc", b"abcd"));
        let t = random_token().unwrap();
        assert_eq!(t.len(), 64);
        check_token(&t).unwrap();
        assert_ne!(t, random_token().unwrap());
        assert!(check_token("short").is_err());
        assert!(check_token("has a space in it, sixteen+").is_err());
        assert!(check_token(&"x".repeat(257)).is_err());
    }

    #[test]
    fn the_token_parameter_is_removed() {
        let u: Uri = "/api/positions?token=abc&format=f64".parse().unwrap();
        assert_eq!(
            without_token(&u).unwrap().to_string(),
            "/api/positions?format=f64"
        );
        let u: Uri = "/api/report?token=abc".parse().unwrap();
        assert_eq!(without_token(&u).unwrap().to_string(), "/api/report");
        let u: Uri = "/api/positions?format=f64".parse().unwrap();
        assert!(without_token(&u).is_none());
    }

    /// A request head with these parts (`None`: header absent).
    #[allow(clippy::too_many_arguments)]
    fn head(
        method: &str,
        uri: &str,
        host: Option<&str>,
        origin: Option<&str>,
        site: Option<&str>,
        auth: Option<&str>,
        kind: Option<&str>,
    ) -> Request {
        let mut b = Request::builder().method(method).uri(uri);
        for (name, value) in [
            ("host", host),
            ("origin", origin),
            ("sec-fetch-site", site),
            ("authorization", auth),
            ("content-type", kind),
        ] {
            if let Some(v) = value {
                b = b.header(name, v);
            }
        }
        b.body(axum::body::Body::empty()).unwrap()
    }

    const TOKEN: &str = "0123456789abcdef0123456789abcdef";

    fn pick(
        options: &'static [&'static str],
    ) -> impl proptest::strategy::Strategy<Value = Option<String>> {
        use proptest::prelude::*;
        prop_oneof![
            Just(None),
            proptest::sample::select(options).prop_map(|s| Some(s.to_string())),
            "[ -~]{0,24}".prop_map(Some),
        ]
    }

    proptest::proptest! {
        /// Whatever the head, `admit` answers without panicking; what it
        /// admits names this server, and unless it is a page file it
        /// carries the token, comes from no other origin, has a JSON body
        /// type when it has a body, and has lost its token parameter; what
        /// it refuses gets 401, 403, 414 or 415. A head that meets every
        /// rule is admitted.
        #[test]
        fn admission(
            method in proptest::sample::select(&["GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"][..]),
            path in proptest::sample::select(&["/", "/main.js", "/api.js", "/api/mesh", "/api/transform", "/api", "/API/mesh", "/main.js/", "/nope"][..]),
            query in proptest::option::of(proptest::prop_oneof![
                proptest::strategy::Just(format!("token={TOKEN}")),
                proptest::strategy::Just(format!("format=f64&token={TOKEN}")),
                proptest::strategy::Just(format!("token=x&token={TOKEN}&a=b")),
                proptest::strategy::Just("token=".to_string()),
                "[a-zA-Z0-9=&_-]{0,16}",
            ]),
            host in pick(&["127.0.0.1:8080", "localhost:8080", "LOCALHOST:8080", "[::1]:8080", "evil.example:8080", "127.0.0.1:8081", "127.0.0.1"]),
            origin in pick(&["http://127.0.0.1:8080", "http://localhost:8080", "null", "http://evil.example", "https://127.0.0.1:8080"]),
            site in pick(&["same-origin", "none", "same-site", "cross-site"]),
            auth in pick(&["Bearer 0123456789abcdef0123456789abcdef", "bearer 0123456789abcdef0123456789abcdef", "Bearer  0123456789abcdef0123456789abcdef ", "Bearer 0123456789abcdef0123456789abcdeF", "Basic eDp5", "Bearer"]),
            kind in pick(&["application/json", "application/json; charset=utf-8", "APPLICATION/JSON", "text/plain", "application/jsonx"]),
        ) {
            let g = Guard::new("127.0.0.1:8080".parse().unwrap(), "127.0.0.1", TOKEN.into(), &["/", "/main.js", "/api.js"]);
            let uri = match &query {
                Some(q) => format!("{path}?{q}"),
                None => path.to_string(),
            };
            let mut request = head(method, &uri, host.as_deref(), origin.as_deref(), site.as_deref(), auth.as_deref(), kind.as_deref());
            let outcome = g.admit(&mut request);
            // The rules, stated directly.
            let host_ok = host.as_deref().is_some_and(|h| {
                ["127.0.0.1:8080", "localhost:8080", "[::1]:8080"].iter().any(|a| a.eq_ignore_ascii_case(h))
            });
            let public = matches!(method, "GET" | "HEAD") && ["/", "/main.js", "/api.js"].contains(&path);
            let same_origin = site.as_deref().is_none_or(|s| s == "same-origin" || s == "none")
                && origin.as_deref().is_none_or(|o| host.as_deref().is_some_and(|h| o.eq_ignore_ascii_case(&format!("http://{h}"))));
            let bearer_ok = auth.as_deref().is_some_and(|a| {
                let a = a.trim();
                a.len() > 7 && a[..7].eq_ignore_ascii_case("bearer ") && a[7..].trim() == TOKEN
            });
            let query_ok = query.as_deref().is_some_and(|q| q.split('&').any(|kv| kv == format!("token={TOKEN}")));
            let json_ok = !matches!(method, "POST" | "PUT" | "PATCH")
                || kind.as_deref().is_some_and(|k| k.split(';').next().unwrap().trim().eq_ignore_ascii_case("application/json"));
            let admissible = host_ok && (public || (same_origin && (bearer_ok || query_ok) && json_ok));
            match outcome {
                Ok(()) => {
                    proptest::prop_assert!(admissible, "admitted {method} {uri} host {host:?} origin {origin:?} site {site:?} auth {auth:?} kind {kind:?}");
                    if !public {
                        let q = request.uri().query().unwrap_or("");
                        proptest::prop_assert!(!q.split('&').any(|kv| kv.starts_with("token=")), "{q}");
                        let others: Vec<&str> = query.as_deref().unwrap_or("").split('&').filter(|kv| !kv.is_empty() && !kv.starts_with("token=")).collect();
                        proptest::prop_assert_eq!(q.split('&').filter(|kv| !kv.is_empty()).collect::<Vec<_>>(), others);
                        proptest::prop_assert_eq!(request.uri().path(), path);
                    }
                }
                Err(e) => {
                    proptest::prop_assert!(!admissible, "refused {method} {uri} host {host:?} origin {origin:?} site {site:?} auth {auth:?} kind {kind:?}: {}", e.message);
                    proptest::prop_assert!([401, 403, 414, 415].contains(&e.status.as_u16()));
                    proptest::prop_assert_eq!(e.status == StatusCode::UNAUTHORIZED, e.www_authenticate);
                }
            }
        }
    }
}
