//! The application layer: everything between a front's input and its output, written once.
//!
//! A front (the command line, the HTTP service, a queue consumer, a batch runner) translates its
//! input into a typed request ([`request`]), calls the pipeline ([`mod@voxelize`], with [`files`]
//! for engines and volume files), a volume operation ([`ops`]) or the jobs' submission path and
//! worker ([`jobs`]), and translates the result (or the
//! [`Error`], classified once in [`error`]) into its output. Nothing here knows HTTP or clap;
//! volumes are kept through the [`store::VolumeStore`] trait and jobs go through the
//! [`queue::JobQueue`] trait, both declared here and implemented by the adapters below
//! (`crate::store`, `crate::queue`), which never call back into the application. Limits are in
//! [`crate::limits`].

pub mod error;
pub mod files;
pub mod jobs;
pub mod metadata;
pub mod ops;
pub mod queue;
pub mod request;
pub mod store;
pub mod voxelize;

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::SystemTime;

pub use crate::limits::Limits;
pub use error::{Error, ErrorKind, Result};
pub use request::{
    CsgExpr, GridOptions, JobSpec, MeshSource, MethodSpec, MorphologyRequest, PreviewRequest,
    PreviewView, QueryRequest, VoxelizeRequest,
};
pub use voxelize::{Loaded, Prepared, Voxelized, prepare, voxelize};

/// sha256 of `b` in lowercase hex (the store contract's, which checks volumes with it).
pub use store::sha256_hex;

/// A fresh id (jobs, volumes, requests): 16 hex digits, unique in this process and unlikely to
/// repeat across processes (a hash of the process id, a counter and the time).
pub fn new_id() -> String {
    use std::hash::{BuildHasher, Hasher};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(u64::from(std::process::id()) << 32 ^ n);
    h.write_u128(
        SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .unwrap_or_default()
            .as_nanos(),
    );
    format!("{:016x}", h.finish())
}

/// RFC 3339 UTC time of `t` (seconds precision).
pub fn rfc3339(t: SystemTime) -> String {
    let secs = t
        .duration_since(SystemTime::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0) as i64;
    let (days, rem) = (secs.div_euclid(86400), secs.rem_euclid(86400));
    // Civil from days (Howard Hinnant).
    let z = days + 719468;
    let era = z.div_euclid(146097);
    let doe = z - era * 146097;
    let yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn rfc3339_dates() {
        assert_eq!(rfc3339(SystemTime::UNIX_EPOCH), "1970-01-01T00:00:00Z");
        assert_eq!(
            rfc3339(SystemTime::UNIX_EPOCH + Duration::from_secs(1_795_000_000)),
            "2026-11-18T11:06:40Z"
        );
        assert_eq!(
            rfc3339(SystemTime::UNIX_EPOCH + Duration::from_secs(951_782_400)),
            "2000-02-29T00:00:00Z"
        );
    }

    #[test]
    fn sha256_of_abc() {
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}

/// What the crate's unit tests share: a tiny closed mesh and a queued job made of it.
#[cfg(test)]
pub(crate) mod testing {
    use bytes::Bytes;

    use super::queue::NewJob;
    use super::{GridOptions, MeshSource, MethodSpec, VoxelizeRequest};

    /// A closed, outward-facing tetrahedron as OBJ.
    pub const TETRA_OBJ: &[u8] =
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

    /// A solid, parity voxelization of [`TETRA_OBJ`] at `resolution`, prepared and ready to queue.
    pub fn tiny_job(id: &str, resolution: u32) -> NewJob {
        let req = VoxelizeRequest {
            source: MeshSource::Bytes {
                bytes: Bytes::from_static(TETRA_OBJ),
                format: None,
            },
            grid: GridOptions::default().spec(resolution).unwrap(),
            padding: 0,
            method: MethodSpec::Bits(crate::engine::Method::Solid),
            fill: crate::engine::fill::Fill::Parity,
            limits: crate::limits::Limits::SERVICE,
        };
        NewJob {
            id: id.into(),
            work: super::prepare(&req).unwrap(),
            spec: super::JobSpec::of(&req),
            name: None,
            owner: None,
            created: String::new(),
        }
    }
}
