//! Errors as RFC 9457 problem documents (`application/problem+json`): one table gives every
//! [`ErrorKind`] its HTTP status and title; its `type` is [`TYPE_BASE`] + the kind's code. The
//! list is also in `openapi.yaml` (components/schemas/Problem) and in the README. Handlers return
//! `Result<_, Problem>` and use `?` on application errors, which convert by `From`.

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};

use crate::app::{Error, ErrorKind};

/// Base of every problem `type`.
pub const TYPE_BASE: &str = "https://voxd.dev/problems/";

/// Every kind with its status and title.
pub const KINDS: [(ErrorKind, u16, &str); 28] = [
    (ErrorKind::InvalidMesh, 422, "The mesh cannot be used"),
    (ErrorKind::UnsupportedMediaType, 415, "Unknown mesh format"),
    (
        ErrorKind::ExternalResource,
        422,
        "The glTF refers to external files",
    ),
    (ErrorKind::TooManyTriangles, 422, "Too many triangles"),
    (ErrorKind::BodyTooLarge, 413, "Request body too large"),
    (ErrorKind::GridTooLarge, 422, "Grid too large"),
    (ErrorKind::InvalidParameter, 400, "Invalid parameter"),
    (ErrorKind::QueueFull, 429, "The job queue is full"),
    (
        ErrorKind::QueueUnavailable,
        503,
        "The job queue cannot be reached",
    ),
    (ErrorKind::NotFound, 404, "Not found"),
    (
        ErrorKind::NotCancelable,
        409,
        "The job has already finished",
    ),
    (ErrorKind::StorageFull, 507, "Storage quota exhausted"),
    (
        ErrorKind::StorageUnavailable,
        503,
        "The store is unavailable",
    ),
    (ErrorKind::EngineFailure, 500, "Voxelization failed"),
    (ErrorKind::ShuttingDown, 503, "The server is shutting down"),
    (
        ErrorKind::MisalignedGrids,
        422,
        "The volumes' grids do not line up",
    ),
    (ErrorKind::WrongVolumeKind, 422, "Wrong kind of volume"),
    (
        ErrorKind::EmptyIntersection,
        422,
        "The intersection is empty",
    ),
    (ErrorKind::Timeout, 408, "Too slow"),
    (ErrorKind::Busy, 503, "The server is busy"),
    (ErrorKind::MethodNotAllowed, 405, "Method not allowed"),
    (ErrorKind::PreconditionFailed, 412, "Precondition failed"),
    (ErrorKind::UriTooLong, 414, "Request target too long"),
    (
        ErrorKind::HeadersTooLarge,
        431,
        "Request header fields too large",
    ),
    (ErrorKind::Unauthorized, 401, "Authentication required"),
    (
        ErrorKind::RateLimited,
        429,
        "Too many requests for this API key",
    ),
    (
        ErrorKind::TooManyJobs,
        429,
        "Too many jobs for this API key",
    ),
    (ErrorKind::Internal, 500, "Internal error"),
];

fn row(kind: ErrorKind) -> (u16, &'static str) {
    KINDS
        .iter()
        .find(|(k, _, _)| *k == kind)
        .map(|&(_, s, t)| (s, t))
        .expect("every kind is in the table")
}

/// A problem document.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Problem {
    #[serde(rename = "type")]
    pub type_: String,
    pub title: String,
    pub status: u16,
    pub detail: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub instance: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub request_id: Option<String>,
    /// Seconds to wait before retrying (queue-full), sent as `Retry-After`.
    #[serde(skip)]
    pub retry_after: Option<u64>,
}

impl Problem {
    pub fn new(kind: ErrorKind, detail: impl Into<String>) -> Problem {
        let (status, title) = row(kind);
        Problem {
            type_: format!("{TYPE_BASE}{}", kind.code()),
            title: title.into(),
            status,
            detail: detail.into(),
            instance: None,
            request_id: None,
            retry_after: None,
        }
    }

    pub fn invalid(detail: impl Into<String>) -> Problem {
        Problem::new(ErrorKind::InvalidParameter, detail)
    }
}

impl From<Error> for Problem {
    fn from(e: Error) -> Problem {
        let mut p = Problem::new(e.kind, e.detail);
        p.retry_after = e.retry_after;
        p
    }
}

impl IntoResponse for Problem {
    fn into_response(self) -> Response {
        let status = StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        let retry = self.retry_after;
        let mut r = (status, serde_json::to_vec(&self).unwrap_or_default()).into_response();
        r.headers_mut().insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/problem+json"),
        );
        if let Some(s) = retry {
            r.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(s));
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::names::Named;

    #[test]
    fn every_kind_has_one_row() {
        for k in ErrorKind::ALL {
            assert_eq!(KINDS.iter().filter(|(r, _, _)| r == k).count(), 1, "{k:?}");
        }
        assert_eq!(KINDS.len(), ErrorKind::ALL.len());
    }
}
