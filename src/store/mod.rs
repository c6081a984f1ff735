//! The store adapters: a directory ([`fs::FsStore`], the default: no extra service on one
//! machine) and an S3 bucket ([`s3::S3Store`], shared by replicas), each implementing the
//! application's [`VolumeStore`] trait (declared in [`crate::app::store`] with the records it
//! keeps). [`StoreSpec`] is what `--store` names.
//!
//! A store holds, per volume, its `.vxl` bytes and its [`VolumeMeta`]; the metadata is the commit
//! point (written last), so an interrupted put leaves nothing listed. It also keeps job records
//! as opaque JSON documents, so that the queue's state lives where the volumes do. A store knows
//! nothing of meshes, engines or the application's workings: it keeps what it is given and
//! checks its quota. Not here: the trait and its records (the application layer's).

pub mod fault;
pub mod fs;
#[cfg(feature = "s3")]
pub mod s3;

use std::path::PathBuf;
use std::pin::Pin;
use std::task::{Context, Poll};

use bytes::Bytes;
use futures_util::Stream;
use sha2::Digest;

// Atomic file writes, which every store uses, where older callers look for them.
pub use crate::atomic;
// The contract's names where the adapters and older callers look for them.
use crate::app::store::hex;
pub use crate::app::store::{
    ByteStream, SourceInfo, StoreError, Usage, VolumeMeta, VolumeStore, Vxl, sha256_hex,
};

/// Where the volumes live, as `--store` (or `VOXD_STORE`) names it: `s3://BUCKET/PREFIX`, or a
/// directory (`file:///path` or a plain path).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StoreSpec {
    Dir(PathBuf),
    #[cfg(feature = "s3")]
    S3(s3::Location),
}

impl StoreSpec {
    pub fn parse(s: &str) -> Result<StoreSpec, String> {
        if let Some(rest) = s.strip_prefix("s3://") {
            #[cfg(feature = "s3")]
            return s3::Location::parse(rest).map(StoreSpec::S3);
            #[cfg(not(feature = "s3"))]
            return Err(format!(
                "{rest:?}: this voxd was built without the s3 feature (cargo build --features s3); use a directory store"
            ));
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
            #[cfg(feature = "s3")]
            StoreSpec::S3(l) => write!(f, "{l}"),
        }
    }
}

/// A volume id as a file name or object key: ids are made by voxd (hex), but a request may name
/// anything.
pub(crate) fn safe_id(id: &str) -> bool {
    !id.is_empty() && id.len() <= 128 && id.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
}

/// Does `vxl` match what `meta` says of it (length, sha256)? The hash is the one `vxl` carries:
/// a put does not hash the bytes again.
pub(crate) fn check_put(meta: &VolumeMeta, vxl: &Vxl) -> Result<(), StoreError> {
    let id = &meta.id;
    if vxl.len() as u64 != meta.bytes {
        return Err(StoreError::Corrupt(format!(
            "volume {id}: the data is {} bytes but its metadata says {} (a torn or damaged file)",
            vxl.len(),
            meta.bytes
        )));
    }
    if vxl.sha256() != meta.sha256 {
        return Err(StoreError::Corrupt(format!(
            "volume {id}: the data's sha256 is {} but its metadata says {:?} (damaged)",
            vxl.sha256(),
            meta.sha256
        )));
    }
    Ok(())
}

/// Do `bytes` (as read back) match what `meta` says of them (length, sha256)?
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
