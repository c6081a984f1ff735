//! The application's one error type: a stable [`ErrorKind`] and a detail saying what to change.
//! Every domain error (mesh, grid, engine, CSG, store) becomes one by `From`, classified here and
//! nowhere else; the HTTP front turns the kind into a problem document (`service/problem.rs`),
//! the command line prints the detail after the file's name. Each kind's code, HTTP status and
//! title are one row of the `error_kinds!` table below (a status is a plain `u16`, so this layer
//! needs no HTTP types); not here: how a problem document is written (`service/problem.rs`).

use serde::{Deserialize, Serialize};

use super::store::StoreError;
use crate::engine::EngineError;
use crate::engine::density::DensityError;
use crate::grid::GridError;
use crate::mesh::MeshError;
use crate::volume::WrongKind;
use crate::volume::csg::CsgError;

/// Declares [`ErrorKind`] from one table, in the manner of Meilisearch's `make_error_codes!`:
/// each row is a variant with its code, HTTP status and title, and the enum, `ALL`, `code()`,
/// `status()`, `title()` and parsing (through [`Named`](crate::names::Named)) are all generated
/// from it, so a kind cannot have a code but no status.
macro_rules! error_kinds {
    ($( $(#[$doc:meta])* $variant:ident = $code:literal, $status:literal, $title:literal; )+) => {
        /// Kinds of failure. Their names (`code`) are stable: they are the last part of the
        /// problem `type` URIs and are kept in job records.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum ErrorKind { $( $(#[$doc])* $variant, )+ }

        impl ErrorKind {
            /// Every kind, in the table's order.
            pub const ALL: [ErrorKind; [$(stringify!($variant)),+].len()] =
                [$(ErrorKind::$variant),+];
            /// The stable name: the problem `type`'s last part.
            pub fn code(self) -> &'static str {
                match self { $(ErrorKind::$variant => $code),+ }
            }
            /// The HTTP status of the kind's problem document.
            pub fn status(self) -> u16 {
                match self { $(ErrorKind::$variant => $status),+ }
            }
            /// The problem document's title (the same for every instance of the kind).
            pub fn title(self) -> &'static str {
                match self { $(ErrorKind::$variant => $title),+ }
            }
        }
    };
}

// One row per kind: `Variant = code, HTTP status, title;`. The codes and statuses are also listed
// in openapi.yaml (components/schemas/Problem), which `tests/openapi_enums.rs` checks against
// this table.
error_kinds! {
    InvalidMesh = "invalid-mesh", 422, "The mesh cannot be used";
    /// The mesh's format is unknown or not a mesh format.
    UnsupportedMediaType = "unsupported-media-type", 415, "Unknown mesh format";
    ExternalResource = "external-resource", 422, "The glTF refers to external files";
    TooManyTriangles = "too-many-triangles", 422, "Too many triangles";
    BodyTooLarge = "body-too-large", 413, "Request body too large";
    GridTooLarge = "grid-too-large", 422, "Grid too large";
    InvalidParameter = "invalid-parameter", 400, "Invalid parameter";
    QueueFull = "queue-full", 429, "The job queue is full";
    /// The shared job queue (Redis) cannot be reached; retry shortly.
    QueueUnavailable = "queue-unavailable", 503, "The job queue cannot be reached";
    NotFound = "not-found", 404, "Not found";
    NotCancelable = "not-cancelable", 409, "The job has already finished";
    StorageFull = "storage-full", 507, "Storage quota exhausted";
    /// The store cannot be reached or fails (I/O, an S3 endpoint down, a timeout, refused
    /// credentials); retry later.
    StorageUnavailable = "storage-unavailable", 503, "The store is unavailable";
    EngineFailure = "engine-failure", 500, "Voxelization failed";
    ShuttingDown = "shutting-down", 503, "The server is shutting down";
    MisalignedGrids = "misaligned-grids", 422, "The volumes' grids do not line up";
    WrongVolumeKind = "wrong-volume-kind", 422, "Wrong kind of volume";
    EmptyIntersection = "empty-intersection", 422, "The intersection is empty";
    /// The work would need more memory than the server's whole budget (`--max-memory`).
    TooMuchMemory = "too-much-memory", 422, "The work needs more memory than the server has";
    /// The request's body or work took longer than allowed.
    Timeout = "timeout", 408, "Too slow";
    /// Too much is in flight (uploads' bytes); retry later.
    Busy = "busy", 503, "The server is busy";
    /// The route does not answer that method.
    MethodNotAllowed = "method-not-allowed", 405, "Method not allowed";
    /// A conditional request's precondition (`If-Match`) does not hold.
    PreconditionFailed = "precondition-failed", 412, "Precondition failed";
    /// The request's target (path and query) is longer than allowed.
    UriTooLong = "uri-too-long", 414, "Request target too long";
    /// The request's head (request line and headers) is larger, or has more headers, than
    /// allowed.
    HeadersTooLarge = "headers-too-large", 431, "Request header fields too large";
    /// An `Expect` header other than `100-continue` (the only expectation HTTP/1.1 defines).
    ExpectationFailed = "expectation-failed", 417, "Expectation failed";
    /// A `Range` no byte of the representation is in (`Content-Range: bytes */length` says
    /// its length).
    RangeNotSatisfiable = "range-not-satisfiable", 416, "Range not satisfiable";
    /// No API key, or not a valid one, where the service requires one (`--api-keys-file`).
    Unauthorized = "unauthorized", 401, "Authentication required";
    /// The API key's role does not allow the request (a `read-only` key asking to write).
    Forbidden = "forbidden", 403, "Not allowed for this API key";
    /// The API key's request rate is exceeded; retry after `Retry-After`.
    RateLimited = "rate-limited", 429, "Too many requests for this API key";
    /// The API key already has its most jobs queued or running.
    TooManyJobs = "too-many-jobs", 429, "Too many jobs for this API key";
    /// The volume does not keep the mesh it was made from (a derived volume, one stored before
    /// meshes were kept) or the store lost it: its Hermite data and dual contouring need it.
    SourceNotKept = "source-not-kept", 409, "The volume does not keep its mesh";
    /// `color=true` on a mesh with no vertex colours and no materials, `material=true` on one
    /// without materials.
    MissingAttributes = "missing-attributes", 422, "The mesh has no colour or materials";
    Internal = "internal", 500, "Internal error";
}

impl crate::names::Named for ErrorKind {
    const WHAT: &'static str = "error kind";
    const ALL: &'static [ErrorKind] = &ErrorKind::ALL;
    fn name(self) -> &'static str {
        self.code()
    }
}

crate::impl_named!(ErrorKind);

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

impl From<crate::engine::colour::ColourError> for Error {
    fn from(e: crate::engine::colour::ColourError) -> Error {
        use crate::engine::colour::ColourError;
        match e {
            ColourError::Canceled(c) => c.into(),
            e => Error::new(ErrorKind::MissingAttributes, e.to_string()),
        }
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
            CsgError::DifferentGrids { .. } => ErrorKind::MisalignedGrids,
            CsgError::NotForDistance(_) => ErrorKind::InvalidParameter,
        };
        Error::new(kind, e.to_string())
    }
}

/// `wrong-volume-kind`, naming the kind given and the kinds the operation takes.
impl From<WrongKind> for Error {
    fn from(e: WrongKind) -> Error {
        Error::new(ErrorKind::WrongVolumeKind, e.to_string())
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

#[cfg(test)]
mod tests {
    use super::ErrorKind;

    /// Codes are distinct and parse back to their kind; statuses are client or server errors.
    #[test]
    fn the_table_is_consistent() {
        let mut codes = std::collections::HashSet::new();
        for k in ErrorKind::ALL {
            assert!(codes.insert(k.code()), "{k:?}'s code is used twice");
            assert_eq!(k.code().parse::<ErrorKind>(), Ok(k));
            assert!((400..600).contains(&k.status()), "{k:?}");
            assert!(!k.title().is_empty(), "{k:?}");
        }
        assert_eq!(ErrorKind::InvalidMesh.to_string(), "invalid-mesh");
        assert_eq!(ErrorKind::StorageFull.status(), 507);
        assert_eq!(ErrorKind::Timeout.title(), "Too slow");
    }
}
