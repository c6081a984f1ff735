//! The directory store: `volumes/{id}.vxl` (the native format) and `volumes/{id}.json`
//! (metadata), `jobs/{id}.json` (job records). Every file is written atomically
//! ([`super::atomic`]); the metadata is written last and is the commit point, so a process
//! killed mid-write leaves either a whole volume or nothing that is listed (leftovers are removed
//! at open).
//!
//! The catalogue is held in memory (read once at open); every file operation runs on tokio's
//! blocking pool, never on a runtime worker, and never under the catalogue's lock.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use async_trait::async_trait;
use bytes::Bytes;

use super::{StoreError, Usage, VolumeMeta, VolumeStore, atomic};

/// How long a successful write probe vouches for the store's health.
const HEALTH_TTL: Duration = Duration::from_secs(30);

pub struct FsStore {
    volumes: PathBuf,
    jobs: PathBuf,
    limit: u64,
    inner: Mutex<Inner>,
}

struct Inner {
    index: BTreeMap<String, VolumeMeta>,
    /// Bytes of the volumes in `index`.
    used: u64,
    /// Bytes of puts in progress: counted against the quota from the check to the commit.
    reserved: u64,
    /// When a write last succeeded (a put or a probe) and whether the last write failed.
    last_ok_write: Option<Instant>,
    last_write_failed: bool,
}

/// Runs blocking file work off the async runtime.
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, StoreError> + Send + 'static,
) -> Result<T, StoreError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| StoreError::Io(std::io::Error::other(e)))?
}

impl FsStore {
    /// Opens (creating) `data_dir/volumes` and `data_dir/jobs`, removes leftovers of interrupted
    /// writes and indexes what is there. Blocking: call it before serving, or off the runtime.
    pub fn open(data_dir: &Path, limit: u64) -> Result<FsStore, StoreError> {
        let volumes = data_dir.join("volumes");
        let jobs = data_dir.join("jobs");
        std::fs::create_dir_all(&volumes)?;
        std::fs::create_dir_all(&jobs)?;
        let mut index = BTreeMap::new();
        let mut files: Vec<PathBuf> = std::fs::read_dir(&volumes)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        files.sort();
        for p in &files {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if name.starts_with('.') {
                let _ = std::fs::remove_file(p); // an interrupted temporary file
                continue;
            }
            if p.extension().is_some_and(|e| e == "json") {
                match std::fs::read(p)
                    .ok()
                    .and_then(|b| serde_json::from_slice::<VolumeMeta>(&b).ok())
                {
                    Some(m) if volumes.join(format!("{}.vxl", m.id)).exists() => {
                        index.insert(m.id.clone(), m);
                    }
                    _ => tracing::warn!(path = %p.display(), "ignoring unreadable volume metadata"),
                }
            }
        }
        for p in &files {
            if p.extension().is_some_and(|e| e == "vxl") {
                let id = p.file_stem().and_then(|s| s.to_str()).unwrap_or("");
                if !index.contains_key(id) {
                    let _ = std::fs::remove_file(p); // data without its commit record
                }
            }
        }
        for e in std::fs::read_dir(&jobs)? {
            let p = e?.path();
            if p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with('.'))
            {
                let _ = std::fs::remove_file(&p);
            }
        }
        tracing::info!(volumes = index.len(), dir = %volumes.display(), "store opened");
        let used = index.values().map(|m| m.bytes).sum();
        Ok(FsStore {
            volumes,
            jobs,
            limit,
            inner: Mutex::new(Inner {
                index,
                used,
                reserved: 0,
                last_ok_write: None,
                last_write_failed: false,
            }),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        // A panic while holding the lock cannot leave the maps half-updated (each update is
        // one statement), so a poisoned lock is still usable.
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn note_write(&self, ok: bool) {
        let mut i = self.lock();
        i.last_write_failed = !ok;
        if ok {
            i.last_ok_write = Some(Instant::now());
        }
    }
}

/// A volume id as a file name: ids are made by voxd (hex), but a request may name anything.
fn safe_id(id: &str) -> bool {
    !id.is_empty() && id.len() <= 128 && id.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
}

#[async_trait]
impl VolumeStore for FsStore {
    async fn put(&self, meta: VolumeMeta, vxl: Bytes) -> Result<(), StoreError> {
        if !safe_id(&meta.id) {
            return Err(StoreError::Corrupt(format!("bad volume id {:?}", meta.id)));
        }
        let need = vxl.len() as u64;
        {
            let mut i = self.lock();
            let used = i.used + i.reserved;
            if used + need > self.limit {
                return Err(StoreError::Full {
                    need,
                    used,
                    limit: self.limit,
                });
            }
            i.reserved += need;
        }
        let dir = self.volumes.clone();
        let m = meta.clone();
        let written = blocking(move || {
            atomic::write(&dir.join(format!("{}.vxl", m.id)), &vxl)?;
            let json = serde_json::to_vec_pretty(&m).expect("metadata serialises");
            atomic::write(&dir.join(format!("{}.json", m.id)), &json)?;
            Ok(())
        })
        .await;
        let mut i = self.lock();
        i.reserved -= need;
        i.last_write_failed = written.is_err();
        if written.is_ok() {
            i.last_ok_write = Some(Instant::now());
            i.used += need;
            if let Some(old) = i.index.insert(meta.id.clone(), meta) {
                i.used -= old.bytes;
            }
        }
        written
    }

    async fn get(&self, id: &str) -> Result<Option<VolumeMeta>, StoreError> {
        Ok(self.lock().index.get(id).cloned())
    }

    async fn read(&self, id: &str) -> Result<Option<Bytes>, StoreError> {
        if !self.lock().index.contains_key(id) {
            return Ok(None);
        }
        let p = self.volumes.join(format!("{id}.vxl"));
        blocking(move || match std::fs::read(&p) {
            Ok(b) => Ok(Some(Bytes::from(b))),
            // Deleted between the check and the read.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e.into()),
        })
        .await
    }

    async fn list(
        &self,
        after: Option<&str>,
        limit: usize,
    ) -> Result<(Vec<VolumeMeta>, bool), StoreError> {
        let i = self.lock();
        let mut it = i
            .index
            .values()
            .filter(|m| after.is_none_or(|a| m.id.as_str() > a));
        let page: Vec<VolumeMeta> = it.by_ref().take(limit).cloned().collect();
        let more = it.next().is_some();
        Ok((page, more))
    }

    async fn delete(&self, id: &str) -> Result<bool, StoreError> {
        let Some(old) = self.lock().index.remove(id) else {
            return Ok(false);
        };
        self.lock().used -= old.bytes;
        let dir = self.volumes.clone();
        let id = id.to_string();
        blocking(move || {
            // Metadata first: once it is gone the volume is gone, whatever happens next.
            std::fs::remove_file(dir.join(format!("{id}.json")))?;
            let _ = std::fs::remove_file(dir.join(format!("{id}.vxl")));
            atomic::sync_dir(&dir)?;
            Ok(true)
        })
        .await
    }

    async fn usage(&self) -> Result<Usage, StoreError> {
        let i = self.lock();
        Ok(Usage {
            bytes: i.used,
            volumes: i.index.len() as u64,
            limit: self.limit,
        })
    }

    /// Healthy when a write succeeded within the last 30 s and the last write did not fail;
    /// otherwise one probe file is written and removed (so an idle store is probed at most
    /// twice a minute, not on every readiness check).
    async fn health(&self) -> Result<(), StoreError> {
        {
            let i = self.lock();
            if !i.last_write_failed && i.last_ok_write.is_some_and(|t| t.elapsed() < HEALTH_TTL) {
                return Ok(());
            }
        }
        let dir = self.volumes.clone();
        let r = blocking(move || {
            let p = dir.join(".probe");
            atomic::write(&p, b"ok")?;
            std::fs::remove_file(&p)?;
            Ok(())
        })
        .await;
        self.note_write(r.is_ok());
        r
    }

    async fn put_job_record(&self, id: &str, record: Bytes) -> Result<(), StoreError> {
        if !safe_id(id) {
            return Err(StoreError::Corrupt(format!("bad job id {id:?}")));
        }
        let p = self.jobs.join(format!("{id}.json"));
        let r = blocking(move || Ok(atomic::write(&p, &record)?)).await;
        self.note_write(r.is_ok());
        r
    }

    async fn job_records(&self) -> Result<Vec<Bytes>, StoreError> {
        let dir = self.jobs.clone();
        blocking(move || {
            let mut out = vec![];
            for e in std::fs::read_dir(&dir)? {
                let p = e?.path();
                if p.extension().is_some_and(|e| e == "json") {
                    match std::fs::read(&p) {
                        Ok(b) => out.push(Bytes::from(b)),
                        Err(e) => {
                            tracing::warn!(path = %p.display(), "unreadable job record: {e}")
                        }
                    }
                }
            }
            Ok(out)
        })
        .await
    }

    fn describe(&self) -> String {
        format!("directory {}", self.volumes.display())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::SourceInfo;

    fn meta(id: &str, bytes: u64) -> VolumeMeta {
        VolumeMeta {
            id: id.into(),
            name: None,
            kind: "bits".into(),
            method: "solid".into(),
            grid: crate::Grid {
                origin: [0.0; 3],
                voxel_size: 1.0,
                dims: [1; 3],
            },
            solid_voxels: 0,
            volume: 0.0,
            source: SourceInfo {
                format: "obj".into(),
                sha256: String::new(),
                triangles: 1,
            },
            diagnostics: None,
            fill: None,
            engine: "cpu".into(),
            created: String::new(),
            bytes,
            sha256: String::new(),
            provenance: None,
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn quota_is_checked_and_reserved_in_one_step() {
        let dir = std::env::temp_dir().join(format!("voxd-fsstore-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let store = std::sync::Arc::new(FsStore::open(&dir, 100).unwrap());
        // Eight concurrent puts of 30 bytes into 100: exactly three fit.
        let puts: Vec<_> = (0..8)
            .map(|n| {
                let s = store.clone();
                tokio::spawn(async move {
                    s.put(meta(&format!("v{n}"), 30), Bytes::from(vec![0u8; 30]))
                        .await
                })
            })
            .collect();
        let mut ok = 0;
        for p in puts {
            match p.await.unwrap() {
                Ok(()) => ok += 1,
                Err(StoreError::Full { .. }) => {}
                Err(e) => panic!("{e}"),
            }
        }
        assert_eq!(ok, 3);
        assert_eq!(store.usage().await.unwrap().bytes, 90);
        assert!(store.health().await.is_ok());
        // Reopened, the same three are there.
        let again = FsStore::open(&dir, 100).unwrap();
        assert_eq!(again.list(None, 10).await.unwrap().0.len(), 3);
        assert!(store.delete("v0").await.unwrap() || store.delete("v1").await.unwrap());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
