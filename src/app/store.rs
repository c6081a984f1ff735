//! The store's side of the application layer: the [`VolumeStore`] trait that every store
//! adapter (`crate::store::fs`, `crate::store::s3`) implements, and the records it keeps
//! ([`VolumeMeta`], [`SourceInfo`]) and its errors ([`StoreError`]). The application owns the
//! contract (as in axum's dependency-injection example); the adapters import it from here and
//! nothing else of the application. Not here: where or how a store keeps its bytes.

use std::pin::Pin;

use async_trait::async_trait;
use bytes::Bytes;
use futures_util::Stream;
use serde::{Deserialize, Serialize};
use sha2::Digest;

use crate::engine::fill::FillReport;
use crate::grid::Grid;
use crate::mesh::MeshDiagnostics;
use crate::volume::VolumeKind;

/// What the API says about a stored volume (the store's catalogue entry).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct VolumeMeta {
    pub id: String,
    pub name: Option<String>,
    /// What the volume holds; serialized by name (`"bits"`, `"density"`, ...), as the string
    /// this field was before the volume model, so stored metadata reads either way.
    pub kind: VolumeKind,
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
    /// For distance volumes (and `method=distance`'s bits): the band, background, bricks,
    /// tiles and active voxels, or the thickness.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distance: Option<DistanceMeta>,
    /// For bit volumes with channels (`color=true`, `material=true`): the channels and the
    /// material table their ids index.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attributes: Option<AttributesMeta>,
    /// The tenant that owns the volume (the API key's tenant that made it); none for volumes
    /// made without keys (or before volumes had owners): only admin keys see those.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub owner: Option<String>,
}

/// What a volume with attribute channels says of them.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct AttributesMeta {
    /// The channels' names (`rgba`: sRGB colour, `material`: u16 material id).
    pub channels: Vec<String>,
    /// The material table of the mesh (id = index), for the `material` channel.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<MaterialMeta>,
}

/// One material of the table.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct MaterialMeta {
    pub id: u16,
    pub name: String,
    /// Linear RGBA in [0, 1] (glTF's `baseColorFactor`, OBJ's `Kd` and `d`).
    pub base_color: [f32; 4],
}

/// What a distance volume's metadata says of it (docs/methods.md, "sdf").
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct DistanceMeta {
    /// The band's half width in voxels, or `"all"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band: Option<serde_json::Value>,
    /// The value outside the band (outside the solid): `band·voxel_size`, or `"inf"`. Inside,
    /// out of band, it is its negation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background: Option<serde_json::Value>,
    /// Stored 8³ bricks, tiles (brick positions inside and out of band), and voxels in band.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bricks: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tiles: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub active_voxels: Option<u64>,
    /// `method=distance`: the thickness used, snapped to the lattice (world units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness: Option<f64>,
}

impl DistanceMeta {
    /// The facts of a sparse distance volume.
    pub fn of_sparse(v: &crate::volume::Sparse<f32>) -> DistanceMeta {
        let bg = v.background();
        let band = if bg.is_finite() {
            serde_json::json!((f64::from(bg) / v.grid().voxel_size).round() as u64)
        } else {
            serde_json::json!("all")
        };
        let active = v
            .bricks()
            .map(|(_, b)| b.iter().filter(|x| x.abs() < bg).count() as u64)
            .sum();
        DistanceMeta {
            band: Some(band),
            background: Some(if bg.is_finite() {
                serde_json::json!(bg)
            } else {
                serde_json::json!("inf")
            }),
            bricks: Some(v.brick_count() as u64),
            tiles: Some(v.tile_count() as u64),
            active_voxels: Some(active),
            thickness: None,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SourceInfo {
    /// The mesh's format (of the mesh inside a gzip'd file).
    pub format: String,
    /// `gzip` when the file or upload was gzip'd.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compression: Option<String>,
    pub sha256: String,
    pub triangles: usize,
    /// The mesh is kept in the store under `sha256` (its source object, [`crate::app::sources`]),
    /// for the Hermite data and dual contouring of the volume; absent (false) for derived
    /// volumes, files given on a command line and volumes stored before meshes were kept.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub kept: bool,
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
    /// describe `vxl` (`Corrupt` otherwise, and nothing is stored): checked against the hash
    /// `vxl` carries, not by hashing again.
    async fn put(&self, meta: VolumeMeta, vxl: Vxl) -> Result<(), StoreError>;
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
    /// The stored `.vxl` bytes as a stream of chunks, for downloads that need not hold a whole
    /// volume: checked while they stream (the store adapters check them with `crate::store::verified`), so damaged data ends the stream with
    /// `Corrupt` before its last byte (a client sees a broken transfer, never a whole one).
    async fn read_stream(&self, id: &str) -> Result<Option<ByteStream>, StoreError>;
    /// Removes a volume; false when there was none.
    async fn delete(&self, id: &str) -> Result<bool, StoreError>;
    async fn usage(&self) -> Result<Usage, StoreError>;
    /// Can the store take writes? Cheap enough for every readiness probe.
    async fn health(&self) -> Result<(), StoreError>;
    /// Writes (replaces) the record of job `id`, durably.
    async fn put_job_record(&self, id: &str, record: Bytes) -> Result<(), StoreError>;
    /// Removes job `id`'s record (none is not an error): old finished jobs are forgotten.
    async fn delete_job_record(&self, id: &str) -> Result<(), StoreError>;
    /// Writes (`Some`) or removes (`None`) several job records (distinct ids), all durable when
    /// this returns: a group commit. A store may do better than one after the other (the
    /// directory store appends them to its log in one write). The result per record.
    ///
    /// Not `durable`: nobody waits for these records to survive a power loss (only a crash of
    /// this process), so a store may leave them to the next durable batch (the directory
    /// store's log writes them without a sync); by default they are made durable all the same.
    async fn put_job_records(
        &self,
        batch: Vec<(String, Option<Bytes>)>,
        _durable: bool,
    ) -> Vec<Result<(), StoreError>> {
        let mut out = Vec::with_capacity(batch.len());
        for (id, bytes) in batch {
            out.push(match bytes {
                Some(b) => self.put_job_record(&id, b).await,
                None => self.delete_job_record(&id).await,
            });
        }
        out
    }
    /// Every job record, in no particular order.
    async fn job_records(&self) -> Result<Vec<Bytes>, StoreError>;
    /// Keeps the uploaded mesh of a queued job (`id` is the job's), so that whichever process
    /// runs the job can read it. Not counted against the volume quota: the queue's capacity and
    /// the body limit bound it.
    async fn put_upload(&self, id: &str, bytes: Bytes) -> Result<(), StoreError>;
    async fn get_upload(&self, id: &str) -> Result<Option<Bytes>, StoreError>;
    /// Removes a job's upload (none is not an error).
    async fn delete_upload(&self, id: &str) -> Result<(), StoreError>;
    /// The uploads kept (job ids), each with when it was written: what the sweep of uploads
    /// that no job refers to reads ([`crate::app::jobs::sweep`]). A store that cannot list
    /// them lists none.
    async fn list_uploads(&self) -> Result<Vec<(String, std::time::SystemTime)>, StoreError> {
        Ok(vec![])
    }
    /// Keeps source object `key` (a mesh a volume was made from: [`crate::app::sources`]) if
    /// it is not there yet; counted against the quota (`Full` when it does not fit). Whether
    /// it was there is not said: a source under a key is always the same bytes.
    async fn put_source(&self, key: &str, bytes: Bytes) -> Result<(), StoreError>;
    /// Source object `key`, as stored (the caller checks it: its bytes carry their hash).
    async fn get_source(&self, key: &str) -> Result<Option<Bytes>, StoreError>;
    /// Removes source object `key` (none is not an error).
    async fn delete_source(&self, key: &str) -> Result<(), StoreError>;
    /// Does a stored volume refer to source `key` (its `source.kept`, its `source.sha256`), or,
    /// in a store shared by replicas, may a put in progress?
    async fn source_referred(&self, key: &str) -> Result<bool, StoreError>;
    /// The source objects kept, each with when it was written.
    async fn list_sources(&self) -> Result<Vec<(String, std::time::SystemTime)>, StoreError>;
    /// Where the store is, for logs.
    fn describe(&self) -> String;
}

/// Is `key` a source object's key: a sha256 in lowercase hex?
pub fn source_key(key: &str) -> bool {
    key.len() == 64
        && key
            .bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

/// A volume's `.vxl` bytes with their sha256, hashed once when made ([`Vxl::new`]): what a
/// store puts. The store checks the metadata against the hash carried here instead of hashing
/// the bytes a second time (the metadata's `sha256` is taken from the same value).
#[derive(Clone, Debug)]
pub struct Vxl {
    bytes: Bytes,
    sha256: String,
}

impl Vxl {
    /// Hashes `bytes` (the only way to make a [`Vxl`], so its hash is always its bytes').
    pub fn new(bytes: impl Into<Bytes>) -> Vxl {
        let bytes = bytes.into();
        let sha256 = sha256_hex(&bytes);
        Vxl { bytes, sha256 }
    }
    pub fn bytes(&self) -> &Bytes {
        &self.bytes
    }
    pub fn into_bytes(self) -> Bytes {
        self.bytes
    }
    /// sha256 of the bytes, lowercase hex.
    pub fn sha256(&self) -> &str {
        &self.sha256
    }
    pub fn len(&self) -> usize {
        self.bytes.len()
    }
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
}

impl From<Bytes> for Vxl {
    fn from(b: Bytes) -> Vxl {
        Vxl::new(b)
    }
}

impl From<Vec<u8>> for Vxl {
    fn from(b: Vec<u8>) -> Vxl {
        Vxl::new(b)
    }
}

impl From<&'static [u8]> for Vxl {
    fn from(b: &'static [u8]) -> Vxl {
        Vxl::new(Bytes::from_static(b))
    }
}

/// Chunks of a stored volume's bytes.
pub type ByteStream = Pin<Box<dyn Stream<Item = Result<Bytes, StoreError>> + Send>>;

/// sha256 of `b` in lowercase hex (volumes' checksums, upload hashes, ids derived from names).
pub fn sha256_hex(b: &[u8]) -> String {
    hex(&sha2::Sha256::digest(b))
}

/// Lowercase hex of `bytes`.
/// `N` bytes from the operating system's random source in lowercase hex (ids, probe and
/// consumer names). The source does not fail once the process runs (std's own `HashMap` seeds
/// panic in the same case); a name that might repeat would be worse than stopping.
pub fn random_hex<const N: usize>() -> String {
    let mut bytes = [0u8; N];
    getrandom::fill(&mut bytes).expect("random numbers from the operating system");
    hex(&bytes)
}

pub fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write;
    let mut s = String::with_capacity(2 * bytes.len());
    for x in bytes {
        let _ = write!(s, "{x:02x}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Metadata as the code before the volume model wrote it (`kind` a plain string; a
    /// density volume with its fill and diagnostics), byte for byte what a store holds today.
    const STORED: &str = r#"{"id":"8cdf143699eff06e","name":"spot","kind":"density","method":"density","grid":{"origin":[-0.6,-0.8,-0.7],"voxel_size":0.02,"dims":[60,90,90]},"solid_voxels":51234,"volume":0.409872,"source":{"format":"obj","sha256":"ab12","triangles":5856},"diagnostics":{"triangles":5856,"vertices":2930,"degenerate_triangles":0,"boundary_edges":0,"non_manifold_edges":0,"watertight":true,"bbox_min":[-0.47,-0.73,-0.66],"bbox_max":[0.47,0.96,1.04]},"fill":{"requested":"parity","used":"parity","odd_parity_columns":0},"engine":"cpu","created":"2026-01-02T03:04:05Z","bytes":12345,"sha256":"cd34"}"#;

    #[test]
    fn metadata_written_before_the_volume_model_still_reads() {
        let meta: VolumeMeta = serde_json::from_str(STORED).unwrap();
        assert_eq!(meta.kind, VolumeKind::Density);
        assert_eq!(meta.id, "8cdf143699eff06e");
        assert_eq!(meta.created, "2026-01-02T03:04:05Z");
        // And it writes back the same bytes: the kind is still its name.
        assert_eq!(serde_json::to_string(&meta).unwrap(), STORED);
        let bits = STORED.replace(r#""kind":"density""#, r#""kind":"bits""#);
        let meta: VolumeMeta = serde_json::from_str(&bits).unwrap();
        assert_eq!(meta.kind, VolumeKind::Bits);
    }

    /// A kind this build does not know is unreadable metadata, with the name in the message.
    #[test]
    fn an_unknown_kind_is_refused_by_name() {
        let odd = STORED.replace(r#""kind":"density""#, r#""kind":"voxels""#);
        let e = serde_json::from_str::<VolumeMeta>(&odd).unwrap_err();
        assert!(
            e.to_string().contains("unknown volume kind \"voxels\""),
            "{e}"
        );
    }
}
