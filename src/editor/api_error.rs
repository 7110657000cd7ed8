//! The editor's error answers: [`ApiError`], a status with the body
//! `{"error": message, "kind": word}`, and the words and messages for a
//! status that comes with none. The leaf of `editor` that the server, the
//! guard and the connection layer all import.

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::json;

use super::session::FrameError;
use crate::error::{ConstraintError, Error, MeshError, ProblemError};

/// An API error: a status and `{"error": message, "kind": word}`.
#[derive(Debug)]
pub struct ApiError {
    pub(super) status: StatusCode,
    pub(super) kind: &'static str,
    pub(super) message: String,
    /// 401: say `WWW-Authenticate: Bearer`.
    pub(super) www_authenticate: bool,
}

impl ApiError {
    pub(super) fn new(status: StatusCode, kind: &'static str, message: String) -> ApiError {
        ApiError {
            status,
            kind,
            message,
            www_authenticate: false,
        }
    }
}

/// `{"error": message, "kind": kind}`.
pub(super) fn error_json(kind: &str, message: &str) -> String {
    json!({"error": message, "kind": kind}).to_string()
}

/// The `kind` of an error answer with `status` when nothing more precise
/// is known.
pub(super) fn status_kind(status: StatusCode) -> &'static str {
    match status.as_u16() {
        400 => "bad-request",
        401 => "unauthorized",
        403 => "forbidden",
        404 => "not-found",
        405 => "method-not-allowed",
        408 => "timeout",
        413 => "too-large",
        414 => "uri-too-long",
        415 => "unsupported-media-type",
        422 => "unprocessable",
        431 => "head-too-large",
        500..=599 => "internal",
        _ => "error",
    }
}

/// A message for an error answer that has none.
pub(super) fn status_message(status: StatusCode) -> String {
    status.canonical_reason().map_or_else(
        || format!("HTTP status {}", status.as_u16()),
        |r| r.to_lowercase(),
    )
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut response = (
            self.status,
            [(header::CONTENT_TYPE, "application/json")],
            error_json(self.kind, &self.message),
        )
            .into_response();
        if self.www_authenticate {
            response
                .headers_mut()
                .insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
        }
        response
    }
}

impl From<Error> for ApiError {
    fn from(e: Error) -> Self {
        let (status, kind) = match e {
            Error::Numerical(_) => (StatusCode::UNPROCESSABLE_ENTITY, "numerical"),
            // Beyond the memory budget or the editor's caps: refused
            // before the work, nothing changed.
            Error::Problem(ProblemError::TooLarge { .. })
            | Error::Constraint(ConstraintError::TooLarge { .. })
            | Error::Mesh(MeshError::TooLarge { .. }) => {
                (StatusCode::PAYLOAD_TOO_LARGE, "too-large")
            }
            _ => (StatusCode::BAD_REQUEST, "bad-request"),
        };
        ApiError::new(status, kind, e.to_string())
    }
}

impl From<FrameError> for ApiError {
    fn from(e: FrameError) -> Self {
        match e {
            FrameError::Engine(e) => e.into(),
            e @ FrameError::NotRepresentable(_) => ApiError::new(
                StatusCode::UNPROCESSABLE_ENTITY,
                "not-representable",
                e.to_string(),
            ),
        }
    }
}

pub(super) fn bad(message: impl Into<String>) -> ApiError {
    ApiError::new(StatusCode::BAD_REQUEST, "bad-request", message.into())
}

pub(super) type ApiResult<T> = Result<T, ApiError>;
