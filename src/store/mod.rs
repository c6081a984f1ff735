//! Where volumes and job records are kept: the [`VolumeStore`] trait and its first
//! implementation, a directory ([`fs::FsStore`], the default: no extra service on one machine).
//!
//! A store holds, per volume, its `.vxl` bytes and its [`VolumeMeta`]; the metadata is the commit
//! point (written last), so an interrupted put leaves nothing listed. It also keeps job records
//! as opaque JSON documents, so that the queue's state lives where the volumes do. A store knows
//! nothing of meshes or engines: it keeps what it is given and checks its quota.

pub mod atomic;
pub mod fs;

use async_trait::async_trait;
use bytes::Bytes;
use serde::{Deserialize, Serialize};

use crate::engine::fill::FillReport;
use crate::grid::Grid;
use crate::mesh::MeshDiagnostics;

/// What the API says about a stored volume (the store's catalogue entry).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct VolumeMeta {
    pub id: String,
    pub name: Option<String>,
    pub kind: String,
    pub method: String,
    pub grid: Grid,
    /// Set voxels.
    pub solid_voxels: u64,
    /// `solid_voxels · voxel_size³` (density: occupied voxels), in mesh units cubed.
    pub volume: f64,
    pub source: SourceInfo,
    pub diagnostics: Option<MeshDiagnostics>,
    /// How the solid was filled: the fill asked for and used, odd-parity columns, a warning
    /// for parity on a mesh that is not watertight (absent for derived volumes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fill: Option<FillReport>,
    pub engine: String,
    /// RFC 3339, UTC.
    pub created: String,
    /// Size of the stored `.vxl`.
    pub bytes: u64,
    /// sha256 of the stored `.vxl`, the basis of download ETags.
    pub sha256: String,
    /// For volumes computed from others: how (the CSG expression, the morphology).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<serde_json::Value>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SourceInfo {
    pub format: String,
    pub sha256: String,
    pub triangles: usize,
}

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error(
        "storing this volume ({need} bytes, data and metadata) would exceed the store's limit of {limit} bytes ({used} used); delete volumes first"
    )]
    Full { need: u64, used: u64, limit: u64 },
    #[error("storage I/O: {0}")]
    Io(#[from] std::io::Error),
    #[error("stored data is unreadable: {0}")]
    Corrupt(String),
}

/// Bytes and volumes stored, against the quota.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Usage {
    /// Everything stored for the volumes: data and metadata (what the quota counts).
    pub bytes: u64,
    pub volumes: u64,
    pub limit: u64,
}

/// A place for volumes and job records. Every method may do I/O and is async; none blocks the
/// caller's thread.
#[async_trait]
pub trait VolumeStore: Send + Sync {
    /// Stores a volume: the quota check and the put are one step (two puts cannot both pass a
    /// check that only one fits), and the quota counts the metadata as well as the data. The
    /// metadata is written last and is the commit point. `meta.bytes` and `meta.sha256` must
    /// describe `vxl` (`Corrupt` otherwise, and nothing is stored).
    async fn put(&self, meta: VolumeMeta, vxl: Bytes) -> Result<(), StoreError>;
    async fn get(&self, id: &str) -> Result<Option<VolumeMeta>, StoreError>;
    /// The stored `.vxl` bytes, verified against the metadata's length and sha256: damaged,
    /// torn or missing data is `Corrupt`, never returned.
    async fn read(&self, id: &str) -> Result<Option<Bytes>, StoreError>;
    /// Up to `limit` volumes with ids after `after`, in id order, and whether more follow.
    async fn list(
        &self,
        after: Option<&str>,
        limit: usize,
    ) -> Result<(Vec<VolumeMeta>, bool), StoreError>;
    /// Removes a volume; false when there was none.
    async fn delete(&self, id: &str) -> Result<bool, StoreError>;
    async fn usage(&self) -> Result<Usage, StoreError>;
    /// Can the store take writes? Cheap enough for every readiness probe.
    async fn health(&self) -> Result<(), StoreError>;
    /// Writes (replaces) the record of job `id`, durably.
    async fn put_job_record(&self, id: &str, record: Bytes) -> Result<(), StoreError>;
    /// Every job record, in no particular order.
    async fn job_records(&self) -> Result<Vec<Bytes>, StoreError>;
    /// Where the store is, for logs.
    fn describe(&self) -> String;
}
