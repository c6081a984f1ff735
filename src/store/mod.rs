//! Where volumes and job records are kept: the [`VolumeStore`] trait and its two
//! implementations, a directory ([`fs::FsStore`], the default: no extra service on one machine)
//! and an S3 bucket ([`s3::S3Store`], shared by replicas). [`StoreSpec`] is what `--store` names.
//!
//! A store holds, per volume, its `.vxl` bytes and its [`VolumeMeta`]; the metadata is the commit
//! point (written last), so an interrupted put leaves nothing listed. It also keeps job records
//! as opaque JSON documents, so that the queue's state lives where the volumes do. A store knows
//! nothing of meshes or engines: it keeps what it is given and checks its quota.

pub mod atomic;
pub mod fs;
mod joblog;
mod packs;
pub mod s3;

use std::path::PathBuf;
use std::pin::Pin;
use std::task::{Context, Poll};

use async_trait::async_trait;
use bytes::Bytes;
use futures_util::Stream;
use serde::{Deserialize, Serialize};
use sha2::Digest;

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
    /// The stored `.vxl` bytes as a stream of chunks, for downloads that need not hold a whole
    /// volume: checked while they stream ([`verified`]), so damaged data ends the stream with
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
    /// Where the store is, for logs.
    fn describe(&self) -> String;
}

/// Where the volumes live, as `--store` (or `VOXD_STORE`) names it: `s3://BUCKET/PREFIX`, or a
/// directory (`file:///path` or a plain path).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StoreSpec {
    Dir(PathBuf),
    S3(s3::Location),
}

impl StoreSpec {
    pub fn parse(s: &str) -> Result<StoreSpec, String> {
        if let Some(rest) = s.strip_prefix("s3://") {
            return s3::Location::parse(rest).map(StoreSpec::S3);
        }
        if let Some(path) = s.strip_prefix("file://") {
            if !path.starts_with('/') {
                return Err(format!(
                    "{s:?}: a file:// store needs an absolute path (file:///var/lib/voxd)"
                ));
            }
            return Ok(StoreSpec::Dir(PathBuf::from(path)));
        }
        if let Some((scheme, _)) = s.split_once("://") {
            return Err(format!(
                "{s:?}: unknown store scheme {scheme:?}; expected s3://BUCKET/PREFIX, file:///PATH or a directory"
            ));
        }
        if s.is_empty() {
            return Err("the store is empty; expected s3://BUCKET/PREFIX or a directory".into());
        }
        Ok(StoreSpec::Dir(PathBuf::from(s)))
    }
}

impl std::fmt::Display for StoreSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StoreSpec::Dir(p) => write!(f, "{}", p.display()),
            StoreSpec::S3(l) => write!(f, "{l}"),
        }
    }
}

/// A volume id as a file name or object key: ids are made by voxd (hex), but a request may name
/// anything.
pub(crate) fn safe_id(id: &str) -> bool {
    !id.is_empty() && id.len() <= 128 && id.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
}

/// Do `bytes` match what `meta` says of them (length, sha256)?
pub(crate) fn check(id: &str, bytes: &[u8], meta: &VolumeMeta) -> Result<(), StoreError> {
    if bytes.len() as u64 != meta.bytes {
        return Err(StoreError::Corrupt(format!(
            "volume {id}: the data is {} bytes but its metadata says {} (a torn or damaged file)",
            bytes.len(),
            meta.bytes
        )));
    }
    let sha = sha256_hex(bytes);
    if sha != meta.sha256 {
        return Err(StoreError::Corrupt(format!(
            "volume {id}: the data's sha256 is {sha} but its metadata says {:?} (damaged)",
            meta.sha256
        )));
    }
    Ok(())
}

/// sha256 of `b` in lowercase hex (volumes' checksums, upload hashes, ids derived from names).
pub fn sha256_hex(b: &[u8]) -> String {
    hex(&sha2::Sha256::digest(b))
}

/// Lowercase hex of `bytes`.
fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write;
    let mut s = String::with_capacity(2 * bytes.len());
    for x in bytes {
        let _ = write!(s, "{x:02x}");
    }
    s
}

/// Chunks of a stored volume's bytes.
pub type ByteStream = Pin<Box<dyn Stream<Item = Result<Bytes, StoreError>> + Send>>;

/// Wraps the raw chunks of volume `id` so that they are checked against `meta`'s length and
/// sha256 as they pass: a chunk that would go past the length, a stream that ends short, or a
/// checksum that differs is `Corrupt`. The checksum is known when the last byte arrives, and
/// the chunk holding it is only passed on once it matches, so a damaged volume never streams
/// out whole. Every store's `read_stream` goes through this.
pub fn verified(
    meta: &VolumeMeta,
    chunks: impl Stream<Item = Result<Bytes, StoreError>> + Send + 'static,
) -> ByteStream {
    Box::pin(Verified {
        id: meta.id.clone(),
        want_len: meta.bytes,
        want_sha: meta.sha256.clone(),
        seen: 0,
        hasher: sha2::Sha256::new(),
        inner: Box::pin(chunks),
        done: false,
    })
}

struct Verified {
    id: String,
    want_len: u64,
    want_sha: String,
    seen: u64,
    hasher: sha2::Sha256,
    inner: ByteStream,
    done: bool,
}

impl Verified {
    fn corrupt(&mut self, why: String) -> Poll<Option<Result<Bytes, StoreError>>> {
        self.done = true;
        let e = StoreError::Corrupt(format!("volume {}: {why}", self.id));
        tracing::error!("{e}");
        Poll::Ready(Some(Err(e)))
    }

    /// Is the finished hash the one the metadata gives?
    fn sha_matches(&mut self) -> Result<(), String> {
        let hex = hex(&std::mem::take(&mut self.hasher).finalize());
        if hex == self.want_sha {
            Ok(())
        } else {
            Err(format!(
                "the data's sha256 is {hex} but its metadata says {:?} (damaged)",
                self.want_sha
            ))
        }
    }
}

impl Stream for Verified {
    type Item = Result<Bytes, StoreError>;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        if self.done {
            return Poll::Ready(None);
        }
        match self.inner.as_mut().poll_next(cx) {
            Poll::Pending => Poll::Pending,
            Poll::Ready(Some(Err(e))) => {
                self.done = true;
                Poll::Ready(Some(Err(e)))
            }
            Poll::Ready(Some(Ok(chunk))) => {
                let seen = self.seen + chunk.len() as u64;
                if seen > self.want_len {
                    let why = format!(
                        "the data is longer than the {} bytes its metadata says",
                        self.want_len
                    );
                    return self.corrupt(why);
                }
                self.seen = seen;
                self.hasher.update(&chunk);
                if seen == self.want_len {
                    // The last byte: check before letting it out.
                    if let Err(why) = self.sha_matches() {
                        return self.corrupt(why);
                    }
                    self.done = true;
                }
                Poll::Ready(Some(Ok(chunk)))
            }
            Poll::Ready(None) if self.seen < self.want_len => {
                let why = format!(
                    "the data is {} bytes but its metadata says {} (a torn or damaged file)",
                    self.seen, self.want_len
                );
                self.corrupt(why)
            }
            Poll::Ready(None) => {
                // Only an empty volume gets here (any other ended at its last byte).
                self.done = true;
                match self.sha_matches() {
                    Ok(()) => Poll::Ready(None),
                    Err(why) => self.corrupt(why),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use futures_util::StreamExt;

    fn meta_of(data: &[u8]) -> VolumeMeta {
        let sha = sha256_hex(data);
        serde_json::from_value(serde_json::json!({
            "id": "v", "name": null, "kind": "bits", "method": "solid",
            "grid": {"origin": [0.0, 0.0, 0.0], "voxel_size": 1.0, "dims": [1, 1, 1]},
            "solid_voxels": 0, "volume": 0.0,
            "source": {"format": "obj", "sha256": "", "triangles": 0},
            "diagnostics": null, "engine": "cpu", "created": "",
            "bytes": data.len(), "sha256": sha,
        }))
        .unwrap()
    }

    /// What comes out of `verified(meta, chunks)`: the bytes, then the error if one ended it.
    async fn run(meta: &VolumeMeta, chunks: Vec<&'static [u8]>) -> (Vec<u8>, Option<String>) {
        let mut s = verified(
            meta,
            futures_util::stream::iter(chunks.into_iter().map(|c| Ok(Bytes::from_static(c)))),
        );
        let mut out = vec![];
        while let Some(c) = s.next().await {
            match c {
                Ok(c) => out.extend_from_slice(&c),
                Err(e) => return (out, Some(e.to_string())),
            }
        }
        (out, None)
    }

    #[tokio::test]
    async fn verified_streams_pass_only_what_matches_the_metadata() {
        let m = meta_of(b"hello world");
        assert_eq!(
            run(&m, vec![b"hello", b" ", b"world"]).await,
            (b"hello world".to_vec(), None)
        );
        // Same length, other bytes: the last chunk is held back.
        let (out, e) = run(&m, vec![b"hello", b" ", b"w0rld"]).await;
        assert_eq!(out, b"hello ");
        assert!(e.unwrap().contains("sha256"));
        // Longer: the chunk crossing the length is refused.
        let (out, e) = run(&m, vec![b"hello", b" world!"]).await;
        assert_eq!(out, b"hello");
        assert!(e.unwrap().contains("longer"));
        // Shorter.
        let (out, e) = run(&m, vec![b"hello"]).await;
        assert_eq!(out, b"hello");
        assert!(e.unwrap().contains("5 bytes"));
    }
}
