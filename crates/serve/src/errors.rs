//! Typed errors: [`ApiError`] is what a request gets back (a status and a JSON body
//! `{"error": {"code": "...", "message": "..."}}`), [`ServeError`] what starting or stopping
//! the server can fail with.

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use std::path::PathBuf;

/// Why a request was refused. Every variant has a stable machine-readable
/// [`code`](ApiError::code) (the `reason` label of `wipdr_serve_rejected_requests_total`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ApiError {
    /// No `Authorization: Bearer` header, or a token not in the tokens file (401).
    #[error("a valid bearer token is needed (Authorization: Bearer TOKEN)")]
    Unauthorized,
    /// No such session for this token (404): another token's session looks the same as none.
    #[error("no session {0} for this token")]
    SessionNotFound(String),
    /// No such route (404).
    #[error("no such route")]
    RouteNotFound,
    /// The body is larger than the server accepts (413).
    #[error("the request body is larger than {limit} bytes")]
    BodyTooLarge {
        /// The limit, bytes.
        limit: usize,
    },
    /// The body is not the JSON the route takes (400).
    #[error("malformed request body: {0}")]
    MalformedBody(String),
    /// A sample of the batch is invalid (400); the batch is refused whole.
    #[error("sample {index}: field {field}: {message}")]
    InvalidSample {
        /// Index of the sample in the batch.
        index: usize,
        /// The field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A sample comes before one the session already has, in stream order (time, then the
    /// sensor rank at equal times) (400); the batch is refused whole.
    #[error(
        "sample {index} ({sensor} at t_ms {t_ms}) comes before the session's latest sample ({last_sensor} at t_ms {last_t_ms}): samples go in time order, and at one millisecond rotation_vector, gyroscope, magnetometer, accelerometer, pressure, wifi"
    )]
    OutOfOrder {
        /// Index of the sample in the batch.
        index: usize,
        /// Its sensor.
        sensor: &'static str,
        /// Its time.
        t_ms: i64,
        /// The sensor of the latest accepted sample.
        last_sensor: &'static str,
        /// The time of the latest accepted sample.
        last_t_ms: i64,
    },
    /// A request field is invalid (400).
    #[error("{field}: {message}")]
    InvalidField {
        /// The field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The session's sample budget is spent (429); the batch is refused whole.
    #[error(
        "the session sends more than {rate} samples a second (burst {burst}); retry in {retry_after_s} s"
    )]
    RateLimited {
        /// Samples a second allowed.
        rate: f64,
        /// Largest batch the bucket holds.
        burst: f64,
        /// When the batch would fit, seconds (rounded up).
        retry_after_s: u64,
    },
    /// The server opens sessions faster than it may (429, with Retry-After).
    #[error("the server opens at most {rate} sessions a second; retry in {retry_after_s} s")]
    TooManyOpens {
        /// Sessions a second allowed.
        rate: f64,
        /// When to try again, seconds (rounded up).
        retry_after_s: u64,
    },
    /// The token has as many open sessions as it may (429).
    #[error("this token has {limit} open sessions, the most it may have: close one first")]
    TooManySessions {
        /// The cap.
        limit: usize,
    },
    /// The session is closed (409): closed by its client, for idleness or by a restart.
    #[error("session {id} is closed ({reason})")]
    SessionClosed {
        /// The session.
        id: String,
        /// Why it was closed.
        reason: String,
    },
    /// The track cannot be given in the asked format (409): `ipin` needs a WGS84 frame.
    #[error("{0}")]
    FormatUnavailable(String),
    /// The server is shutting down (503).
    #[error("the server is shutting down")]
    ShuttingDown,
    /// Something failed inside the server (500); the detail is logged, not sent.
    #[error("internal error")]
    Internal,
}

/// The code of an error response, left in the response's extensions for the metrics.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorCode(pub &'static str);

/// The JSON body of an error response.
#[derive(Debug, Serialize)]
struct ErrorBody<'a> {
    error: ErrorDetail<'a>,
}

#[derive(Debug, Serialize)]
struct ErrorDetail<'a> {
    code: &'a str,
    message: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    index: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    field: Option<&'a str>,
}

impl ApiError {
    /// The HTTP status.
    pub fn status(&self) -> StatusCode {
        match self {
            Self::Unauthorized => StatusCode::UNAUTHORIZED,
            Self::SessionNotFound(_) | Self::RouteNotFound => StatusCode::NOT_FOUND,
            Self::BodyTooLarge { .. } => StatusCode::PAYLOAD_TOO_LARGE,
            Self::MalformedBody(_)
            | Self::InvalidSample { .. }
            | Self::OutOfOrder { .. }
            | Self::InvalidField { .. } => StatusCode::BAD_REQUEST,
            Self::RateLimited { .. } | Self::TooManyOpens { .. } | Self::TooManySessions { .. } => {
                StatusCode::TOO_MANY_REQUESTS
            }
            Self::SessionClosed { .. } | Self::FormatUnavailable(_) => StatusCode::CONFLICT,
            Self::ShuttingDown => StatusCode::SERVICE_UNAVAILABLE,
            Self::Internal => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }

    /// The stable code (`error.code` of the body).
    pub fn code(&self) -> &'static str {
        match self {
            Self::Unauthorized => "unauthorized",
            Self::SessionNotFound(_) => "session_not_found",
            Self::RouteNotFound => "route_not_found",
            Self::BodyTooLarge { .. } => "body_too_large",
            Self::MalformedBody(_) => "malformed_body",
            Self::InvalidSample { .. } => "invalid_sample",
            Self::OutOfOrder { .. } => "out_of_order",
            Self::InvalidField { .. } => "invalid_field",
            Self::RateLimited { .. } => "rate_limited",
            Self::TooManyOpens { .. } => "too_many_opens",
            Self::TooManySessions { .. } => "too_many_sessions",
            Self::SessionClosed { .. } => "session_closed",
            Self::FormatUnavailable(_) => "format_unavailable",
            Self::ShuttingDown => "shutting_down",
            Self::Internal => "internal",
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let (index, field) = match &self {
            Self::InvalidSample { index, field, .. } => (Some(*index), Some(field.as_str())),
            Self::OutOfOrder { index, .. } => (Some(*index), None),
            Self::InvalidField { field, .. } => (None, Some(field.as_str())),
            _ => (None, None),
        };
        let body = ErrorBody {
            error: ErrorDetail {
                code: self.code(),
                message: self.to_string(),
                index,
                field,
            },
        };
        let mut response = (self.status(), axum::Json(body)).into_response();
        if let Self::RateLimited { retry_after_s, .. } | Self::TooManyOpens { retry_after_s, .. } =
            &self
            && let Ok(v) = HeaderValue::from_str(&retry_after_s.to_string())
        {
            response.headers_mut().insert(header::RETRY_AFTER, v);
        }
        response.extensions_mut().insert(ErrorCode(self.code()));
        response
    }
}

/// Why the server could not start, run or stop.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The tokens file could not be read.
    #[error("tokens file {path}: {source}")]
    TokensFile {
        /// The file.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The tokens file holds a bad line (the token itself is never repeated).
    #[error("tokens file {path}: line {line}: {reason}")]
    BadToken {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The database failed.
    #[error("database {path}: {source}")]
    Database {
        /// The file.
        path: PathBuf,
        /// Cause.
        source: rusqlite::Error,
    },
    /// A setting is invalid.
    #[error("config: {field}: {message}")]
    Config {
        /// The setting.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
    /// Binding or serving the socket failed.
    #[error("serving on {addr}: {source}")]
    Socket {
        /// The address.
        addr: String,
        /// Cause.
        source: std::io::Error,
    },
}
