//! The application's one error type: a stable [`ErrorKind`] and a detail saying what to change.
//! Every domain error (mesh, grid, engine, CSG, store) becomes one by `From`, classified here and
//! nowhere else; the HTTP front turns the kind into a problem document (`service/problem.rs`),
//! the command line prints the detail after the file's name.

use serde::{Deserialize, Serialize};

use super::store::StoreError;
use crate::engine::EngineError;
use crate::engine::density::DensityError;
use crate::grid::GridError;
use crate::mesh::MeshError;
use crate::volume::csg::CsgError;

/// Kinds of failure. Their names (`code`) are stable: they are the last part of the problem
/// `type` URIs and are kept in job records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    InvalidMesh,
    /// The mesh's format is unknown or not a mesh format.
    UnsupportedMediaType,
    ExternalResource,
    TooManyTriangles,
    BodyTooLarge,
    GridTooLarge,
    InvalidParameter,
    QueueFull,
    /// The shared job queue (Redis) cannot be reached; retry shortly.
    QueueUnavailable,
    NotFound,
    NotCancelable,
    StorageFull,
    /// The store cannot be reached or fails (I/O, an S3 endpoint down, a timeout, refused
    /// credentials); retry later.
    StorageUnavailable,
    EngineFailure,
    ShuttingDown,
    MisalignedGrids,
    WrongVolumeKind,
    EmptyIntersection,
    /// The request's body or work took longer than allowed.
    Timeout,
    /// Too much is in flight (uploads' bytes); retry later.
    Busy,
    /// The route does not answer that method.
    MethodNotAllowed,
    /// A conditional request's precondition (`If-Match`) does not hold.
    PreconditionFailed,
    /// The request's target (path and query) is longer than allowed.
    UriTooLong,
    /// The request's head (request line and headers) is larger, or has more headers, than
    /// allowed.
    HeadersTooLarge,
    /// No API key, or not a valid one, where the service requires one (`--api-keys-file`).
    Unauthorized,
    /// The API key's request rate is exceeded; retry after `Retry-After`.
    RateLimited,
    /// The API key already has its most jobs queued or running.
    TooManyJobs,
    Internal,
}

impl crate::names::Named for ErrorKind {
    const WHAT: &'static str = "error kind";
    const ALL: &'static [ErrorKind] = &[
        ErrorKind::InvalidMesh,
        ErrorKind::UnsupportedMediaType,
        ErrorKind::ExternalResource,
        ErrorKind::TooManyTriangles,
        ErrorKind::BodyTooLarge,
        ErrorKind::GridTooLarge,
        ErrorKind::InvalidParameter,
        ErrorKind::QueueFull,
        ErrorKind::QueueUnavailable,
        ErrorKind::NotFound,
        ErrorKind::NotCancelable,
        ErrorKind::StorageFull,
        ErrorKind::StorageUnavailable,
        ErrorKind::EngineFailure,
        ErrorKind::ShuttingDown,
        ErrorKind::MisalignedGrids,
        ErrorKind::WrongVolumeKind,
        ErrorKind::EmptyIntersection,
        ErrorKind::Timeout,
        ErrorKind::Busy,
        ErrorKind::MethodNotAllowed,
        ErrorKind::PreconditionFailed,
        ErrorKind::UriTooLong,
        ErrorKind::HeadersTooLarge,
        ErrorKind::Unauthorized,
        ErrorKind::RateLimited,
        ErrorKind::TooManyJobs,
        ErrorKind::Internal,
    ];
    fn name(self) -> &'static str {
        self.code()
    }
}

crate::impl_named!(ErrorKind);

impl ErrorKind {
    pub fn code(self) -> &'static str {
        match self {
            ErrorKind::InvalidMesh => "invalid-mesh",
            ErrorKind::UnsupportedMediaType => "unsupported-media-type",
            ErrorKind::ExternalResource => "external-resource",
            ErrorKind::TooManyTriangles => "too-many-triangles",
            ErrorKind::BodyTooLarge => "body-too-large",
            ErrorKind::GridTooLarge => "grid-too-large",
            ErrorKind::InvalidParameter => "invalid-parameter",
            ErrorKind::QueueFull => "queue-full",
            ErrorKind::QueueUnavailable => "queue-unavailable",
            ErrorKind::NotFound => "not-found",
            ErrorKind::NotCancelable => "not-cancelable",
            ErrorKind::StorageFull => "storage-full",
            ErrorKind::StorageUnavailable => "storage-unavailable",
            ErrorKind::EngineFailure => "engine-failure",
            ErrorKind::ShuttingDown => "shutting-down",
            ErrorKind::MisalignedGrids => "misaligned-grids",
            ErrorKind::WrongVolumeKind => "wrong-volume-kind",
            ErrorKind::EmptyIntersection => "empty-intersection",
            ErrorKind::Timeout => "timeout",
            ErrorKind::Busy => "busy",
            ErrorKind::MethodNotAllowed => "method-not-allowed",
            ErrorKind::PreconditionFailed => "precondition-failed",
            ErrorKind::UriTooLong => "uri-too-long",
            ErrorKind::HeadersTooLarge => "headers-too-large",
            ErrorKind::Unauthorized => "unauthorized",
            ErrorKind::RateLimited => "rate-limited",
            ErrorKind::TooManyJobs => "too-many-jobs",
            ErrorKind::Internal => "internal",
        }
    }
}

/// An application error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{detail}")]
pub struct Error {
    pub kind: ErrorKind,
    pub detail: String,
    /// Seconds after which retrying may succeed (a full queue, a store that is not ready).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retry_after: Option<u64>,
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn new(kind: ErrorKind, detail: impl Into<String>) -> Error {
        Error {
            kind,
            detail: detail.into(),
            retry_after: None,
        }
    }
    pub fn invalid(detail: impl Into<String>) -> Error {
        Error::new(ErrorKind::InvalidParameter, detail)
    }
    pub fn internal(detail: impl Into<String>) -> Error {
        Error::new(ErrorKind::Internal, detail)
    }
    pub fn not_found(what: &str, id: &str) -> Error {
        Error::new(ErrorKind::NotFound, format!("no {what} with id {id:?}"))
    }
    pub fn retry_after(mut self, secs: u64) -> Error {
        self.retry_after = Some(secs);
        self
    }
    /// The same error with `context: ` in front of the detail.
    pub fn context(mut self, context: impl std::fmt::Display) -> Error {
        self.detail = format!("{context}: {}", self.detail);
        self
    }
}

impl From<MeshError> for Error {
    fn from(e: MeshError) -> Error {
        let kind = match &e {
            MeshError::ExternalRefused { .. } => ErrorKind::ExternalResource,
            MeshError::TooManyTriangles { .. } | MeshError::CountOverLimit { .. } => {
                ErrorKind::TooManyTriangles
            }
            MeshError::UnknownFormat => ErrorKind::UnsupportedMediaType,
            MeshError::TooLarge(_) => ErrorKind::BodyTooLarge,
            _ => ErrorKind::InvalidMesh,
        };
        Error::new(kind, e.to_string())
    }
}

impl From<GridError> for Error {
    fn from(e: GridError) -> Error {
        let kind = match e {
            // Over a limit of the grid: its voxels, an axis, or its extent in voxels from the
            // world origin (past 2^40 voxel boundaries are not distinct numbers). Each depends on
            // the mesh or on how the parameters combine, which the API document cannot say.
            GridError::TooManyVoxels { .. }
            | GridError::AxisTooLong { .. }
            | GridError::Unrepresentable { .. } => ErrorKind::GridTooLarge,
            // A resolution needs a mesh with an extent: the mesh's fault.
            GridError::NoExtent => ErrorKind::InvalidMesh,
            // A parameter out of its documented range.
            GridError::ZeroResolution
            | GridError::BadVoxelSize(_)
            | GridError::BadOrigin(_)
            | GridError::ZeroDims(_) => ErrorKind::InvalidParameter,
        };
        Error::new(kind, e.to_string())
    }
}

impl From<EngineError> for Error {
    fn from(e: EngineError) -> Error {
        let kind = match e {
            // A vertex too far from the grid for the fixed-point lattice: the mesh's fault.
            EngineError::OutOfRange { .. } => ErrorKind::InvalidMesh,
            // Stopped at a check point: past its deadline, or canceled (a canceled job's
            // record says canceled; a canceled request has no one left to tell).
            EngineError::Canceled(_) => ErrorKind::Timeout,
            _ => ErrorKind::EngineFailure,
        };
        Error::new(kind, e.to_string())
    }
}

/// Classified like the engine error it is (the map above).
impl From<crate::cancel::Canceled> for Error {
    fn from(c: crate::cancel::Canceled) -> Self {
        EngineError::from(c).into()
    }
}

impl From<DensityError> for Error {
    fn from(e: DensityError) -> Error {
        match e {
            DensityError::Engine(e) => e.into(),
            DensityError::Grid { .. } => Error::new(ErrorKind::GridTooLarge, e.to_string()),
        }
    }
}

impl From<CsgError> for Error {
    fn from(e: CsgError) -> Error {
        let kind = match e {
            CsgError::Misaligned { .. } => ErrorKind::MisalignedGrids,
            CsgError::NoOverlap => ErrorKind::EmptyIntersection,
            CsgError::NoOperands => ErrorKind::InvalidParameter,
            CsgError::TooFarApart { .. } => ErrorKind::GridTooLarge,
        };
        Error::new(kind, e.to_string())
    }
}

impl From<StoreError> for Error {
    fn from(e: StoreError) -> Error {
        match e {
            StoreError::Full { .. } => Error::new(ErrorKind::StorageFull, e.to_string()),
            StoreError::Io(_) => {
                Error::new(ErrorKind::StorageUnavailable, e.to_string()).retry_after(5)
            }
            StoreError::Corrupt(_) => Error::new(ErrorKind::Internal, e.to_string()),
        }
    }
}

impl From<crate::codec::CodecError> for Error {
    fn from(e: crate::codec::CodecError) -> Error {
        Error::new(ErrorKind::InvalidParameter, e.to_string())
    }
}
