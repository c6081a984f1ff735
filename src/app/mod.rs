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

pub mod attributes;
pub mod carry;
pub mod cost;
pub mod distance;
pub mod error;
pub mod files;
pub mod hermite;
pub mod jobs;
pub mod memory;
pub mod mesh;
pub mod metadata;
pub mod ops;
pub mod queue;
pub mod request;
pub mod sources;
pub mod store;
pub mod stream;
pub mod voxelize;

use std::time::{Duration, SystemTime};

pub use crate::limits::Limits;
pub use error::{Error, ErrorKind, Result};
pub use request::{
    CsgExpr, GridOptions, JobSpec, MeshSource, MethodSpec, MorphologyRequest, PreviewRequest,
    PreviewView, QueryRequest, VoxelizeRequest,
};
pub use voxelize::{Loaded, Prepared, Voxelized, prepare, voxelize};

/// sha256 of `b` in lowercase hex (the store contract's, which checks volumes with it).
pub use store::sha256_hex;

/// A fresh id (jobs, volumes, requests): 16 hex digits of 8 random bytes from the operating
/// system (`getrandom`), so ids do not repeat across processes or restarts.
pub fn new_id() -> String {
    store::random_hex::<8>()
}

/// RFC 3339 UTC time of `t` (seconds precision), by `humantime`. Times outside what RFC 3339
/// writes (before 1970 or after 9999, a clock set very wrong) are clamped to its ends instead
/// of failing.
pub fn rfc3339(t: SystemTime) -> String {
    let last = SystemTime::UNIX_EPOCH + Duration::from_secs(253_402_300_799); // 9999-12-31T23:59:59Z
    humantime::format_rfc3339_seconds(t.clamp(SystemTime::UNIX_EPOCH, last)).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

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

    /// Clocks set outside RFC 3339's years give its ends, not a panic.
    #[test]
    fn rfc3339_clamps_times_it_cannot_write() {
        assert_eq!(
            rfc3339(SystemTime::UNIX_EPOCH - Duration::from_secs(1)),
            "1970-01-01T00:00:00Z"
        );
        assert_eq!(
            rfc3339(SystemTime::UNIX_EPOCH + Duration::from_secs(300_000_000_000)),
            "9999-12-31T23:59:59Z"
        );
    }

    /// 16 lowercase hex digits, different each time.
    #[test]
    fn ids_are_16_hex_digits_and_differ() {
        let ids: std::collections::HashSet<String> = (0..1000).map(|_| new_id()).collect();
        assert_eq!(ids.len(), 1000);
        for id in &ids {
            assert_eq!(id.len(), 16, "{id}");
            assert!(
                id.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f')),
                "{id}"
            );
        }
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
            attributes: Default::default(),
            limits: crate::limits::Limits::SERVICE,
        };
        NewJob {
            id: id.into(),
            work: super::prepare(&req).unwrap(),
            spec: super::JobSpec::of(&req),
            name: None,
            owner: None,
            request_id: None,
            created: String::new(),
        }
    }
}
