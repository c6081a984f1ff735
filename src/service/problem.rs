//! Errors as RFC 9457 problem documents (`application/problem+json`), one stable `type` URI per
//! kind of failure. The list is in `openapi.yaml` (components/schemas/Problem) and in the README.

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};

/// Base of every problem `type`.
pub const TYPE_BASE: &str = "https://voxd.dev/problems/";

/// Kinds of failure, each with its status and `type` slug.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    InvalidMesh,
    UnsupportedMediaType,
    ExternalResource,
    TooManyTriangles,
    BodyTooLarge,
    GridTooLarge,
    InvalidParameter,
    QueueFull,
    NotFound,
    NotCancelable,
    StorageFull,
    EngineFailure,
    ShuttingDown,
    MisalignedGrids,
    WrongVolumeKind,
    EmptyIntersection,
    Internal,
}

impl Kind {
    pub const ALL: [Kind; 17] = [
        Kind::MisalignedGrids,
        Kind::WrongVolumeKind,
        Kind::EmptyIntersection,
        Kind::InvalidMesh,
        Kind::UnsupportedMediaType,
        Kind::ExternalResource,
        Kind::TooManyTriangles,
        Kind::BodyTooLarge,
        Kind::GridTooLarge,
        Kind::InvalidParameter,
        Kind::QueueFull,
        Kind::NotFound,
        Kind::NotCancelable,
        Kind::StorageFull,
        Kind::EngineFailure,
        Kind::ShuttingDown,
        Kind::Internal,
    ];

    pub fn slug(self) -> &'static str {
        match self {
            Kind::InvalidMesh => "invalid-mesh",
            Kind::UnsupportedMediaType => "unsupported-media-type",
            Kind::ExternalResource => "external-resource",
            Kind::TooManyTriangles => "too-many-triangles",
            Kind::BodyTooLarge => "body-too-large",
            Kind::GridTooLarge => "grid-too-large",
            Kind::InvalidParameter => "invalid-parameter",
            Kind::QueueFull => "queue-full",
            Kind::NotFound => "not-found",
            Kind::NotCancelable => "not-cancelable",
            Kind::StorageFull => "storage-full",
            Kind::EngineFailure => "engine-failure",
            Kind::ShuttingDown => "shutting-down",
            Kind::MisalignedGrids => "misaligned-grids",
            Kind::WrongVolumeKind => "wrong-volume-kind",
            Kind::EmptyIntersection => "empty-intersection",
            Kind::Internal => "internal",
        }
    }

    pub fn status(self) -> StatusCode {
        match self {
            Kind::InvalidMesh | Kind::GridTooLarge | Kind::TooManyTriangles => {
                StatusCode::UNPROCESSABLE_ENTITY
            }
            Kind::ExternalResource
            | Kind::MisalignedGrids
            | Kind::WrongVolumeKind
            | Kind::EmptyIntersection => StatusCode::UNPROCESSABLE_ENTITY,
            Kind::UnsupportedMediaType => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            Kind::BodyTooLarge => StatusCode::PAYLOAD_TOO_LARGE,
            Kind::InvalidParameter => StatusCode::BAD_REQUEST,
            Kind::QueueFull => StatusCode::TOO_MANY_REQUESTS,
            Kind::NotFound => StatusCode::NOT_FOUND,
            Kind::NotCancelable => StatusCode::CONFLICT,
            Kind::StorageFull => StatusCode::INSUFFICIENT_STORAGE,
            Kind::EngineFailure | Kind::Internal => StatusCode::INTERNAL_SERVER_ERROR,
            Kind::ShuttingDown => StatusCode::SERVICE_UNAVAILABLE,
        }
    }

    pub fn title(self) -> &'static str {
        match self {
            Kind::InvalidMesh => "The mesh cannot be used",
            Kind::UnsupportedMediaType => "Unknown mesh format",
            Kind::ExternalResource => "The glTF refers to external files",
            Kind::TooManyTriangles => "Too many triangles",
            Kind::BodyTooLarge => "Request body too large",
            Kind::GridTooLarge => "Grid too large",
            Kind::InvalidParameter => "Invalid parameter",
            Kind::QueueFull => "The job queue is full",
            Kind::NotFound => "Not found",
            Kind::NotCancelable => "The job has already finished",
            Kind::StorageFull => "Storage quota exhausted",
            Kind::EngineFailure => "Voxelization failed",
            Kind::ShuttingDown => "The server is shutting down",
            Kind::MisalignedGrids => "The volumes' grids do not line up",
            Kind::WrongVolumeKind => "Wrong kind of volume",
            Kind::EmptyIntersection => "The intersection is empty",
            Kind::Internal => "Internal error",
        }
    }
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
    /// Seconds to wait before retrying (queue-full).
    #[serde(skip)]
    pub retry_after: Option<u64>,
}

impl Problem {
    pub fn new(kind: Kind, detail: impl Into<String>) -> Problem {
        Problem {
            type_: format!("{TYPE_BASE}{}", kind.slug()),
            title: kind.title().into(),
            status: kind.status().as_u16(),
            detail: detail.into(),
            instance: None,
            request_id: None,
            retry_after: None,
        }
    }
    pub fn retry_after(mut self, secs: u64) -> Problem {
        self.retry_after = Some(secs);
        self
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
